// Tissue in physical units (tissue.h): presets and the surface model's calibration.

#include "bisturi/sim/tissue.h"

#include <array>
#include <cmath>
#include <string>

#include "bisturi/sim/errors.h"

namespace bisturi::sim {
namespace {

// Moduli from elastography and indentation studies (docs/sim/tissue.md lists them with their
// ranges); Poisson's ratios near incompressible, as soft tissue is mostly water.
constexpr std::array<TissuePreset, 5> kPresets{{
    {"liver",
     {4.0, 0.45, 1060.0, 0.01},
     "healthy liver 2.3-5.9 kPa by transient and shear-wave elastography (Sandrin et al. 2003, "
     "Ultrasound Med. Biol. 29(12); Castera et al. 2008, J. Hepatol. 48(5))"},
    {"kidney",
     {4.4, 0.45, 1050.0, 0.01},
     "healthy renal cortex about 4.4 kPa by shear-wave elastography (Grenier et al. 2013, "
     "Diagn. Interv. Imaging 94(5))"},
    {"spleen",
     {8.0, 0.45, 1054.0, 0.01},
     "healthy spleen about 5-10 kPa by MR and shear-wave elastography (Talwalkar et al. 2009, "
     "AJR 193(1))"},
    {"vessel-wall",
     {300.0, 0.45, 1060.0, 0.005},
     "arterial wall 0.1-1 MPa incremental modulus at physiological pressure (Holzapfel et al. "
     "2000, J. Elasticity 61)"},
    {"fat",
     {3.25, 0.45, 920.0, 0.02},
     "adipose tissue 3.25 +- 0.91 kPa by indentation (Samani et al. 2007, Phys. Med. Biol. 52)"},
}};

}  // namespace

std::span<const TissuePreset> tissue_presets() {
  return kPresets;
}

const TissuePreset& tissue_preset(std::string_view name) {
  for (const TissuePreset& p : kPresets) {
    if (p.name == name) return p;
  }
  std::string names;
  for (const TissuePreset& p : kPresets)
    names += (names.empty() ? "" : ", ") + std::string(p.name);
  throw SimInputError("material: no tissue preset '" + std::string(name) + "' (presets: " + names +
                      ")");
}

void check_elastic(const ElasticMaterial& m) {
  auto fail = [](const char* name, double value, const char* range) {
    throw SimInputError(std::string("material: ") + name + " must be " + range + ", got " +
                        std::to_string(value));
  };
  if (!std::isfinite(m.youngs_modulus_kPa) || m.youngs_modulus_kPa <= 0.0)
    fail("youngs_modulus_kPa", m.youngs_modulus_kPa, "positive and finite");
  if (!std::isfinite(m.poisson_ratio) || m.poisson_ratio < 0.0 || m.poisson_ratio >= 0.5)
    fail("poisson_ratio", m.poisson_ratio, "in [0, 0.5)");
  if (!std::isfinite(m.density_kg_per_m3) || m.density_kg_per_m3 <= 0.0)
    fail("density_kg_per_m3", m.density_kg_per_m3, "positive and finite");
  if (!std::isfinite(m.retardation_time_s) || m.retardation_time_s < 0.0)
    fail("retardation_time_s", m.retardation_time_s, "non-negative and finite");
}

Material calibrate_surface(const ElasticMaterial& m, double thickness_m) {
  check_elastic(m);
  if (!std::isfinite(thickness_m) || thickness_m <= 0.0) {
    throw SimInputError("material: thickness must be positive and finite, got " +
                        std::to_string(thickness_m));
  }
  const double e_pa = m.youngs_modulus_kPa * 1e3;
  Material out;
  out.structural_N_per_m = std::sqrt(3.0) / 2.0 * e_pa * thickness_m;
  out.shear_N_per_m = 0.25 * out.structural_N_per_m;
  out.bending_N_per_m = 0.05 * out.structural_N_per_m;
  out.spring_damping_N_s_per_m = out.structural_N_per_m * m.retardation_time_s;
  out.drag_per_s = 1.0;
  out.density_kg_per_m3 = m.density_kg_per_m3;
  out.thickness_m = thickness_m;
  out.bulk_modulus_Pa = e_pa / (3.0 * (1.0 - 2.0 * m.poisson_ratio));
  return out;
}

}  // namespace bisturi::sim
