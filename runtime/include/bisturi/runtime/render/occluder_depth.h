#pragma once
// Occlusion culling on the CPU from the frame's own occluders, conservative: a box is called
// hidden only when every point of it that either eye could see lies behind a triangle that is
// drawn in the same frame, so culling what it hides leaves every pixel as it was.
//
// Each eye's view is a coarse grid of cells. An occluder (a solid's drawn level) covers a cell
// when the cell's centre lies in one of its triangles that the rasterizer draws (those facing the
// eye; all of them for a two-sided, open surface) and no edge of the occluder's outline crosses
// the cell: then the whole cell lies inside the outline, however small the triangles are. An edge
// belongs to the outline when it joins a drawn triangle to one not drawn, or bounds the surface.
// The covered cell's depth is the farthest corner (clip w) of the drawn triangles touching it, a
// bound on the nearest surface at any point of the cell. The grid keeps, per cell, the nearest
// such bound over the occluders; a box is hidden when its nearest corner lies behind every cell
// under its screen rectangle, in both eyes (the depth-pyramid test of hierarchical z-buffers,
// Greene, Kass and Miller 1993, with the pyramid's one level a coarse grid).

#include <array>
#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "bisturi/runtime/render/frustum.h"

namespace bisturi::render {

/// Each edge of a triangle list once, with the triangles on its two sides.
struct TriangleEdges {
  static constexpr std::int32_t kBoundary = -1;     ///< no second triangle
  static constexpr std::int32_t kNonManifold = -2;  ///< more than two triangles share it
  std::vector<std::array<std::uint32_t, 2>> vertices;
  std::vector<std::array<std::int32_t, 2>> triangles;
};

/// The edges of `indices` (three per triangle) over vertices below `vertex_count`.
TriangleEdges triangle_edges(std::span<const std::uint32_t> indices, std::size_t vertex_count);

class OccluderDepth {
 public:
  /// Starts a frame with nothing occluding: a grid of `columns` x `rows` cells over each eye's
  /// view (`view_projection` with Vulkan depth; `eye_mm` the eye's position in the world).
  void begin(const std::array<glm::dmat4, 2>& view_projection,
             const std::array<glm::dvec3, 2>& eye_mm, std::uint32_t columns, std::uint32_t rows);
  /// Adds a drawn surface: `vertices` holds `stride` floats per vertex, the first three its
  /// world position (mm); `indices` its drawn triangles, counter-clockwise seen from outside;
  /// `edges` those of `indices`. `two_sided`: both sides are drawn (an open surface).
  void add(std::span<const float> vertices, std::size_t stride,
           std::span<const std::uint32_t> indices, const TriangleEdges& edges, bool two_sided);
  /// Whether no point of `box` can show in either eye past the surfaces added so far.
  [[nodiscard]] bool hides(const Aabb& box) const;

  /// The cells covered in `eye` (for tests and figures).
  [[nodiscard]] std::size_t covered_cells(int eye) const;

 private:
  struct Eye {
    glm::dmat4 view_projection{1.0};
    glm::dvec3 position_mm{0.0};
    std::vector<float> depth;  ///< per cell: the nearest covering bound (clip w); +inf: none
  };
  void project(const Eye& eye, std::span<const float> vertices, std::size_t stride);
  void add_to(Eye& eye, std::span<const float> vertices, std::size_t stride,
              std::span<const std::uint32_t> indices, const TriangleEdges& edges, bool two_sided);
  [[nodiscard]] bool hides_in(const Eye& eye, const Aabb& box) const;

  std::array<Eye, 2> eyes_;
  std::uint32_t columns_ = 0;
  std::uint32_t rows_ = 0;
  // Scratch of one surface in one eye.
  std::vector<glm::dvec3> screen_;     ///< per vertex: cell coordinates x, y and clip w
  std::vector<std::int8_t> facing_;    ///< per triangle: +1 drawn facing, -1 drawn reversed, 0 not
  std::vector<std::uint8_t> centred_;  ///< per cell: its centre in a drawn triangle
  std::vector<std::uint8_t> crossed_;  ///< per cell: an outline edge touches it
  std::vector<float> farthest_;        ///< per cell: the farthest corner of those touching it
};

}  // namespace bisturi::render
