#pragma once
// Plane cuts through the DLFL: the cross-section loops of a surface mesh with a plane.
//
// Finding the loops. A CutIndex is a bounding-volume hierarchy over the mesh's edges, built once
// per mesh and reused for any number of planes. A cut visits only the nodes whose boxes the plane
// crosses and tests only their edges, giving every edge that crosses the plane (the seeds); each
// loop is then walked face to face through the DLFL from one seed: in a face, from the side where
// the loop enters to the side where it leaves (corner -> next), then across that side's edge into
// the neighbouring face (partner), until the walk comes back to its first side (a closed loop) or
// reaches a labelled (bounding) face, where the surface ends (an open loop, walked both ways from
// the seed so its points run from one boundary to the other). Points come out in order; only the
// faces along the loops are read.
//
// Vertices on the plane. Every decision uses one sign per vertex: the signed distance
// dot(normal, p - point), with a distance of exactly 0 counted as positive (a symbolic
// perturbation of the plane towards -normal). An edge crosses when its two vertices have different
// signs, so an edge lying in the plane never crosses, a vertex in the plane belongs to one side,
// and within a face the crossed sides alternate entering/leaving: loops are never broken or
// doubled. A crossing at a vertex in the plane is that vertex exactly; repeated consecutive points
// (the loop passing through such a vertex) are kept once. A loop that collapses to fewer than
// three distinct points (closed) or two (open), the plane touching the surface at a vertex or
// along edges, is dropped.
//
// Surface points. Marching-cubes vertices lie on the true surface, but the mesh's edges are
// chords of it, so a cut point on an edge lies inside a convex surface by up to L^2 k / 8 (L: the
// edge's length, k: the surface's normal curvature along it). With CutOptions::surface_points,
// each point also gets an estimate on the smooth surface: the edge (a, b) at parameter t is
// lifted by t (1 - t) / 2 * dot(n_b - n_a, b - a) along the interpolated normal (the quadratic
// through a and b whose tangents are normal to the vertex normals n_a, n_b; area-weighted face
// normals), then moved within the plane to where the lifted surface meets it. Curvature is
// estimated from the mesh, so the correction works on any mesh, not only extracted ones.
//
// The index keeps a reference to the mesh and copies nothing but edge ends; it is valid while
// the mesh's topology_version() and positions are unchanged (rebuild it after editing).

#include <cstddef>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"

namespace bisturi {

/// The plane through `point` with unit normal `normal` (the constructor of a cut normalizes it).
struct Plane {
  glm::dvec3 point{0.0};
  glm::dvec3 normal{0.0, 0.0, 1.0};
};

struct CutOptions {
  /// Also estimate each point's position on the smooth surface (CutLoop::surface_points).
  bool surface_points = true;
};

struct CutLoop {
  /// The plane's intersection with the mesh, in walk order (an open loop: boundary to boundary).
  std::vector<glm::dvec3> points;
  /// The same points moved onto the smooth surface the mesh samples (empty without
  /// CutOptions::surface_points); they stay in the plane.
  std::vector<glm::dvec3> surface_points;
  /// The crossed edge of each point.
  std::vector<EdgeId> edges;
  /// True when the walk came back to its start; false when it ended at labelled faces.
  bool closed = false;
  /// Faces the loop passes through (labelled faces not counted).
  std::size_t faces_touched = 0;
  /// Median length of the crossed edges: the mesh's resolution along the loop.
  double edge_length = 0.0;
};

struct PlaneCut {
  Plane plane;  ///< normal of unit length
  std::vector<CutLoop> loops;
  std::size_t faces_touched = 0;   ///< over all loops
  std::size_t nodes_visited = 0;   ///< hierarchy nodes whose box the plane crosses
  std::size_t edges_tested = 0;    ///< edges tested against the plane (in visited leaves)
  std::size_t crossing_edges = 0;  ///< edges that cross the plane
};

/// A bounding-volume hierarchy over a mesh's edges for plane cuts.
class CutIndex {
 public:
  /// Builds the hierarchy (leaves of at most leaf_size edges, split at the median of the longest
  /// axis). O(E log E).
  explicit CutIndex(const Dlfl& mesh, std::size_t leaf_size = 8);

  /// All loops of the plane. Throws InputError for a zero or non-finite normal or point.
  [[nodiscard]] PlaneCut cut(const Plane& plane, const CutOptions& options = {}) const;

  [[nodiscard]] const Dlfl& mesh() const { return *mesh_; }
  [[nodiscard]] std::size_t node_count() const { return nodes_.size(); }
  [[nodiscard]] std::size_t edge_count() const { return edges_.size(); }
  /// Bytes held by the hierarchy.
  [[nodiscard]] std::size_t memory_bytes() const;

 private:
  struct Node {
    float lo[3];
    float hi[3];
    std::uint32_t first;  ///< leaf: first item; inner: left child (right child is first + 1)
    std::uint32_t count;  ///< leaf: items (> 0); inner: 0
  };
  const Dlfl* mesh_;
  std::vector<Node> nodes_;
  std::vector<EdgeId> edges_;        // leaf order
  std::vector<std::uint32_t> ends_;  // two vertex indices per item, leaf order
};

/// The same loops found by testing every edge of the mesh (the reference and the baseline of the
/// benchmark); edges_tested is the number of live edges.
PlaneCut cut_plane_brute_force(const Dlfl& mesh, const Plane& plane,
                               const CutOptions& options = {});

}  // namespace bisturi
