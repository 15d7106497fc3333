#pragma once
// Material of one soft solid, SI units. Spring constants are per spring (N/m): a structural
// spring on every edge, shear springs across face diagonals, bending springs across every edge
// (between the vertices that follow the edge in its two faces). Damping acts along each spring
// (N*s/m) and as a mass-proportional drag (1/s). Masses come from density x thickness x area
// (the surface is a membrane of the given thickness), shared equally among a face's corners.
// Closed solids keep their volume with a pressure term: p = bulk_modulus * (V0 - V) / V0.

namespace bisturi::sim {

struct Material {
  double structural_N_per_m = 200.0;
  double shear_N_per_m = 50.0;
  double bending_N_per_m = 10.0;
  double spring_damping_N_s_per_m = 0.05;
  double drag_per_s = 1.0;
  double density_kg_per_m3 = 1050.0;  ///< soft tissue is about water
  double thickness_m = 0.003;         ///< membrane thickness used for masses
  double bulk_modulus_Pa = 2000.0;    ///< volume term; 0 turns it off; open solids have none
};

/// Throws SimInputError naming the first negative or non-finite parameter (density and
/// thickness must be positive).
void check_material(const Material& material);

}  // namespace bisturi::sim
