#pragma once
// The spring network of a soft solid, read off its DLFL: one structural spring per edge, shear
// springs across the diagonals of faces with more than three corners, and one bending spring per
// interior edge between the vertices that follow the edge in its two faces (the opposite
// vertices of two triangles). Labelled (boundary) faces and point spheres contribute nothing.
// Springs are sorted and unique, so the list (and every sum over it) has one deterministic order.

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"
#include "bisturi/sim/material.h"

namespace bisturi::sim {

enum class SpringKind : std::uint8_t { Structural, Shear, Bending };

struct Spring {
  std::uint32_t a = 0;  ///< vertex index (a < b)
  std::uint32_t b = 0;
  double rest_m = 0.0;
  double k_N_per_m = 0.0;
  SpringKind kind = SpringKind::Structural;
};

/// Springs of `mesh` with rest lengths from `rest_positions_m` (indexed by vertex index).
std::vector<Spring> build_springs(const Dlfl& mesh, const std::vector<glm::dvec3>& rest_positions_m,
                                  const Material& material);

/// The faces around the vertices (indices), sorted and unique.
std::vector<FaceId> faces_around(const Dlfl& mesh, std::span<const std::uint32_t> vertices);

/// The springs build_springs gives that have at least one end in the region (region[v] != 0),
/// found from `faces` (faces_around the region's vertices) and their edges only: the local
/// update after an edit (a cut) that changed nothing outside the region.
std::vector<Spring> build_springs_near(const Dlfl& mesh,
                                       const std::vector<glm::dvec3>& rest_positions_m,
                                       const Material& material,
                                       const std::vector<std::uint8_t>& region,
                                       std::span<const FaceId> faces);

/// The unlabelled faces fan-triangulated (vertex indices, counter-clockwise seen from outside),
/// with the face each triangle came from: the surface the BVH, the haptic proxy and the volume
/// term see.
struct SurfaceTriangles {
  std::vector<std::uint32_t> indices;  ///< 3 per triangle
  std::vector<FaceId> face_of;         ///< 1 per triangle
  [[nodiscard]] std::size_t size() const { return face_of.size(); }
};
SurfaceTriangles triangulate_surface(const Dlfl& mesh);
/// triangulate_surface into `out` after an edit that changed only the faces in `changed`
/// (sorted, unique; a face that died needs not be listed): the others' triangles are copied
/// from `before`, the last triangulation. The result is the same, in the same order.
void triangulate_changed_faces(const Dlfl& mesh, const SurfaceTriangles& before,
                               std::span<const FaceId> changed, SurfaceTriangles& out);

}  // namespace bisturi::sim
