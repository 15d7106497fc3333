#include "bisturi/sim/instruments.h"

#include <glm/geometric.hpp>

#include "bisturi/sim/collision.h"

namespace bisturi::sim {

double capsule_distance(const Capsule& c, const glm::dvec3& p) {
  double t = 0.0;
  return glm::length(p - closest_point_on_segment(p, c.a_m, c.b_m, t)) - c.radius_m;
}

}  // namespace bisturi::sim
