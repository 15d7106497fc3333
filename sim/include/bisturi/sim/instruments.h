#pragma once
// Instrument shapes in metres: capsules (a segment with a radius). A probe is one capsule (its
// tip is the haptic point), a grasper two jaw capsules, a scalpel blade the segment of its edge.

#include <glm/vec3.hpp>

namespace bisturi::sim {

struct Capsule {
  glm::dvec3 a_m{0.0};
  glm::dvec3 b_m{0.0};
  double radius_m = 0.0;
};

/// Distance from p to the capsule's surface (negative inside).
double capsule_distance(const Capsule& capsule, const glm::dvec3& p_m);

struct Grasper {
  Capsule jaw_a;
  Capsule jaw_b;
};

struct Blade {
  glm::dvec3 edge_from_m{0.0};  ///< the cutting edge, heel to tip
  glm::dvec3 edge_to_m{0.0};
};

}  // namespace bisturi::sim
