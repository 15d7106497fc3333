#pragma once
// Small pieces the implicit integrator's files share (integrator.cpp, integrator_sleep.cpp,
// integrator_multirate.cpp): the volume term and the solve's tolerances.

#include <cstddef>
#include <cstdint>
#include <limits>

#include <glm/geometric.hpp>

#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim::integrator_detail {

constexpr std::uint32_t kNotFree = std::numeric_limits<std::uint32_t>::max();

/// The volume term applies to closed bodies with a rest volume (their fans are closed).
inline bool has_volume_term(const SoftBody& body) {
  return body.closed() && body.rest_volume_m3() > 0.0;
}

/// The enclosed volume for 6 V = six_v, measured outward whatever the faces' winding (as
/// SoftBody::volume_m3()).
inline double outward_volume(const SoftBody& body, double six_v) {
  return body.orientation() * (six_v / 6.0);
}

/// The volume term's energy 1/2 K (V - V0)^2 / V0.
inline double volume_term_energy(const SoftBody& body, double volume) {
  const double v0 = body.rest_volume_m3();
  return 0.5 * body.material().bulk_modulus_Pa * (volume - v0) * (volume - v0) / v0;
}

/// The pressure factor p / 6 of the volume term at `volume` (times 6 dV/dx it is the force),
/// signed by the faces' winding as the gradient is.
inline double pressure_factor(const SoftBody& body, double volume) {
  const double v0 = body.rest_volume_m3();
  return body.orientation() * body.material().bulk_modulus_Pa * (v0 - volume) / v0 / 6.0;
}

/// A solved vertex's net force at the start of a substep: weight, external load, drag, its
/// springs' forces (with the h H v term) and, for closed bodies, the pressure.
/// `gradient`: the vertex's volume gradient, null without a volume term (the gradient array is
/// then empty: no element of it may be named).
inline glm::dvec3 net_force(double mass, const glm::dvec3& g, const glm::dvec3& external,
                            double drag, const glm::dvec3& velocity, const glm::dvec3& springs,
                            double p6, const glm::dvec3* gradient) {
  glm::dvec3 f = mass * g + external - drag * mass * velocity + springs;
  if (gradient != nullptr) f += p6 * *gradient;
  return f;
}

/// A right-hand-side row, four lanes: h f and a zero pad.
inline void store_rhs_row(double* row, double h, const glm::dvec3& f) {
  row[0] = h * f.x;
  row[1] = h * f.y;
  row[2] = h * f.z;
  row[3] = 0.0;
}

/// The solve's squared tolerances for a substep of length h over rows of summed squared masses
/// weight2: the absolute one (the residual force under cg_weight_fraction of the weights, or
/// the floor per row, times h) and the relative one.
struct CgTolerances {
  double abs2 = 0.0, rel2 = 0.0;
};
inline CgTolerances cg_tolerances(const IntegratorOptions& options, double h, double weight2,
                                  std::size_t rows) {
  const glm::dvec3 g = options.gravity_m_s2;
  const double g2 = glm::dot(g, g);
  const double frac2 = options.cg_weight_fraction * options.cg_weight_fraction;
  const double floor2 = options.cg_force_floor_N * options.cg_force_floor_N;
  return {h * h * (frac2 * g2 * weight2 + floor2 * double(rows)),
          options.cg_relative_tolerance * options.cg_relative_tolerance};
}

}  // namespace bisturi::sim::integrator_detail
