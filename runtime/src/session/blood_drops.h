#pragma once
// The blood's particles as the renderer draws them: one small octahedron per particle, all in one
// solid of a fixed topology (as many as the blood may hold), so each frame only moves vertices.
// Octahedra past the particles in the field collapse to a point (no area: nothing is drawn).

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"

namespace bisturi::runtime {

class BloodDrops {
 public:
  /// Room for `capacity` particles drawn `radius_mm` across from their centres.
  BloodDrops(std::size_t capacity, double radius_mm);
  /// Places the drops at `centres_mm` (those past capacity are not drawn).
  void place(const std::vector<glm::dvec3>& centres_mm);
  [[nodiscard]] const Dlfl& mesh() const { return mesh_; }

 private:
  double radius_mm_;
  std::size_t capacity_;
  Dlfl mesh_;
  std::vector<VertexId> vertex_;  ///< 6 per drop: +x, -x, +y, -y, +z, -z
};

}  // namespace bisturi::runtime
