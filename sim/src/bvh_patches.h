#pragma once
// Spatially coherent patches of a body's surface triangles, for the two-level BVH of
// collision.cpp: each patch is one Embree geometry, so a cut rebuilds the BVHs of the patches
// whose triangles changed and keeps the others (a full rebuild of the 20k-vertex sphere's 38.7k
// triangles costs about 18 ms on this project's Zen 1 machine, over half of a 5 cm cut).
//
// Faces are ordered by the Morton code of a centroid in the body's box at the first build and cut
// into runs of about kTrianglesPerPatch triangles (whole faces). A face keeps its patch for the
// life of the body; a face made later (a cut's new faces) joins the patch whose code range holds
// its centroid's code, so it lands among its neighbours.

#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/springs.h"

namespace bisturi::sim {

class SurfacePatches {
 public:
  static constexpr std::size_t kTrianglesPerPatch = 4096;

  /// Assigns every face of `triangles` anew (positions x give the box and the centroids).
  void assign(const SurfaceTriangles& triangles, const std::vector<glm::dvec3>& x);
  /// Assigns the faces of `triangles` that have no patch yet; the others keep theirs.
  void assign_new_faces(const SurfaceTriangles& triangles, const std::vector<glm::dvec3>& x);
  /// Per patch, the indices of its triangles in `triangles`, ascending.
  [[nodiscard]] std::vector<std::vector<std::uint32_t>> split(
      const SurfaceTriangles& triangles) const;
  [[nodiscard]] std::size_t count() const { return first_code_.size(); }

 private:
  [[nodiscard]] std::uint32_t code_of(const SurfaceTriangles& triangles, std::size_t triangle,
                                      const std::vector<glm::dvec3>& x) const;

  glm::dvec3 lo_{0.0};
  glm::dvec3 scale_{0.0};                     // maps the box onto [0, 1024) per axis
  std::vector<std::uint32_t> patch_of_face_;  // by face handle; kUnassigned: none yet
  std::vector<std::uint32_t> first_code_;     // the smallest code in each patch, ascending
};

/// A primitive of a patch's Embree geometry that no current triangle has: after a cut, a patch
/// keeps its built BVH with such primitives in it (queries skip them) instead of rebuilding.
constexpr std::uint32_t kDeadTriangle = 0xffffffffu;

/// Matches a patch's primitives (their corner triples as Embree holds them, 3 per primitive)
/// with the triangles `home` (indices into the body's triangle `indices`) that have the same
/// corners in the same order: prim_triangle[i] is the triangle of primitive i, or kDeadTriangle.
/// Returns the triangles of `home` that no primitive matched, in home's order. Each triangle
/// matches one primitive at most.
std::vector<std::uint32_t> match_primitives(const std::vector<std::uint32_t>& prim_corners,
                                            const std::vector<std::uint32_t>& home,
                                            const std::vector<std::uint32_t>& indices,
                                            std::vector<std::uint32_t>& prim_triangle);

}  // namespace bisturi::sim
