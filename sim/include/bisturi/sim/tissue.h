#pragma once
// Tissue in physical units: a linear-elastic material (Young's modulus, Poisson's ratio,
// density, a Kelvin-Voigt retardation time for its damping), presets for organs with their
// sources (docs/sim/tissue.md), and the calibration that turns one into the surface model's
// spring constants and volume term (Material).
//
// The calibration (docs/sim/tissue.md says why and what it reaches): the surface is a membrane of
// thickness t standing for the tissue under it. A triangle network of springs k has the in-plane
// stiffness (Young's modulus times thickness) 2 k / sqrt(3), so k = sqrt(3) / 2 E t for the
// structural springs, whatever the mesh's resolution; shear and bending springs keep their
// fractions of it (1/4 and 1/20). The volume term's bulk modulus is the continuum's,
// E / (3 (1 - 2 nu)). The springs' damping is k tau: each spring's stress is E (strain + tau
// strain rate). Masses are density x t x area.

#include <span>
#include <string_view>

#include "bisturi/sim/material.h"

namespace bisturi::sim {

struct ElasticMaterial {
  double youngs_modulus_kPa = 4.0;
  double poisson_ratio = 0.45;
  double density_kg_per_m3 = 1050.0;
  /// Kelvin-Voigt retardation time: stress = E (strain + tau d strain / dt).
  double retardation_time_s = 0.01;
};

struct TissuePreset {
  std::string_view name;
  ElasticMaterial material;
  std::string_view source;  ///< where the modulus comes from (docs/sim/tissue.md)
};

/// liver, kidney, spleen, vessel-wall, fat.
std::span<const TissuePreset> tissue_presets();
/// The preset named `name`; throws SimInputError naming the presets otherwise.
const TissuePreset& tissue_preset(std::string_view name);

/// Throws SimInputError naming the first parameter out of range (E > 0, 0 <= nu < 0.5,
/// density > 0, tau >= 0, all finite).
void check_elastic(const ElasticMaterial& material);

/// The surface model's thickness when none is given (the membrane's mass and stiffness).
constexpr double kDefaultTissueThickness_m = 0.003;

/// The surface model's material for `material` (see above); drag 1/s. Checks it first.
Material calibrate_surface(const ElasticMaterial& material,
                           double thickness_m = kDefaultTissueThickness_m);

}  // namespace bisturi::sim
