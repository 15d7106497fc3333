#pragma once
// Grasping: when the jaws close, the vertices within capture distance of either jaw are held;
// held vertices become kinematic and follow the grasper (translation of its reference point)
// until released.

#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/instruments.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

class Grasp {
 public:
  /// Captures the vertices within capture_m of either jaw's surface; returns how many. The
  /// grasper's reference point is the midpoint of the jaw tips.
  std::size_t close(SoftBody& body, const Grasper& grasper, double capture_m = 0.001);
  /// Moves the held vertices with the grasper's reference point (metres).
  void drag(SoftBody& body, const glm::dvec3& reference_m);
  void release(SoftBody& body);
  [[nodiscard]] const std::vector<VertexId>& held() const { return held_; }

 private:
  std::vector<VertexId> held_;
  std::vector<glm::dvec3> offsets_;
};

}  // namespace bisturi::sim
