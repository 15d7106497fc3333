#pragma once
// The openings of a solid: its labelled boundary faces (DLFL boundary extension, seed section
// 4.2), each one boundary loop, e.g. the lips of an incision, and the mouths of its wounds (the
// vertices where faces marked kInteriorFaces meet the outside), one loop for them all. A solid
// with a hole (a labelled boundary face) is drawn two-sided, its inside showing through the hole;
// a wound closed by walls is not (the walls are its inside). Each loop's box is a portal through
// which the structures inside the solid can be seen (seed section 3.2).

#include <cstdint>
#include <vector>

#include "bisturi/runtime/render/frustum.h"
#include "bisturi/scene/dlfl.h"

namespace bisturi::render {

class SolidBoundary {
 public:
  /// Finds the boundary loops again (a new topology).
  void rebuild(const Dlfl& mesh);
  /// The loops' boxes at the mesh's current positions (same topology as the last rebuild).
  void refit(const Dlfl& mesh);

  /// Any opening: a hole or a wound's mouth.
  [[nodiscard]] bool open() const { return !loops_.empty(); }
  /// A hole through the surface (a labelled boundary face): its inside shows.
  [[nodiscard]] bool holed() const { return holes_ > 0; }
  [[nodiscard]] const std::vector<Aabb>& portals() const { return portals_; }
  [[nodiscard]] std::uint64_t topology_version() const { return topology_version_; }

 private:
  std::vector<std::vector<std::uint32_t>> loops_;  ///< vertex indices of each loop
  std::size_t holes_ = 0;                          ///< the first loops: labelled faces
  std::vector<Aabb> portals_;
  std::uint64_t topology_version_ = ~std::uint64_t{0};
};

}  // namespace bisturi::render
