#include "bisturi/sim/material.h"

#include <cmath>
#include <string>

#include "bisturi/sim/errors.h"

namespace bisturi::sim {

void check_material(const Material& m) {
  auto need = [](double value, const char* name, bool positive) {
    if (!std::isfinite(value) || value < 0.0 || (positive && value == 0.0)) {
      throw SimInputError(std::string("material: ") + name + " must be " +
                          (positive ? "positive" : "non-negative") + " and finite, got " +
                          std::to_string(value));
    }
  };
  need(m.structural_N_per_m, "structural_N_per_m", false);
  need(m.shear_N_per_m, "shear_N_per_m", false);
  need(m.bending_N_per_m, "bending_N_per_m", false);
  need(m.spring_damping_N_s_per_m, "spring_damping_N_s_per_m", false);
  need(m.drag_per_s, "drag_per_s", false);
  need(m.density_kg_per_m3, "density_kg_per_m3", true);
  need(m.thickness_m, "thickness_m", true);
  need(m.bulk_modulus_Pa, "bulk_modulus_Pa", false);
}

}  // namespace bisturi::sim
