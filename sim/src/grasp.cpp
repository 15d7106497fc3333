#include "bisturi/sim/grasp.h"

namespace bisturi::sim {

std::size_t Grasp::close(SoftBody& body, const Grasper& grasper, double capture_m) {
  release(body);
  const glm::dvec3 reference = 0.5 * (grasper.jaw_a.b_m + grasper.jaw_b.b_m);
  const Dlfl& mesh = body.mesh();
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (!mesh.alive(v) || body.mass(v) <= 0.0) continue;
    const glm::dvec3& p = body.position(v);
    if (capsule_distance(grasper.jaw_a, p) <= capture_m ||
        capsule_distance(grasper.jaw_b, p) <= capture_m) {
      held_.push_back(v);
      offsets_.push_back(p - reference);
      body.set_kinematic_target(v, p);
    }
  }
  return held_.size();
}

void Grasp::drag(SoftBody& body, const glm::dvec3& reference_m) {
  for (std::size_t i = 0; i < held_.size(); ++i) {
    body.set_kinematic_target(held_[i], reference_m + offsets_[i]);
  }
}

void Grasp::release(SoftBody& body) {
  for (VertexId v : held_)
    body.release_kinematic(v);
  held_.clear();
  offsets_.clear();
}

}  // namespace bisturi::sim
