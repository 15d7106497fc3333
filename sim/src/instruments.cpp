#include "bisturi/sim/instruments.h"

#include <algorithm>

#include <glm/geometric.hpp>

namespace bisturi::sim {

double capsule_distance(const Capsule& c, const glm::dvec3& p) {
  const glm::dvec3 ab = c.b_m - c.a_m;
  const double l2 = glm::dot(ab, ab);
  const double t = l2 > 0.0 ? std::clamp(glm::dot(p - c.a_m, ab) / l2, 0.0, 1.0) : 0.0;
  return glm::length(p - (c.a_m + t * ab)) - c.radius_m;
}

}  // namespace bisturi::sim
