#pragma once
// Cutting: a scalpel blade swept across a surface opens an incision with the DLFL operators.
//
// 1. Path. The blade's contact points (metres) are followed by a walk over the surface vertices
//    (snapped: the incision starts and ends at the vertices nearest to the first and last point,
//    and every step goes to a vertex of a face around the current one that comes closer to the
//    target and stays near the blade's line). A step across a face (a diagonal) splits that face
//    with insert_edge; a diagonal that would pass closer than sliver_fraction x the face's mean
//    edge length to another corner is not taken (no slivers: the path snaps to existing vertices
//    and edges instead). The walk stops at the first boundary vertex after the start.
// 2. Incision. Every path vertex that must open (interior ones, and an end on the boundary) is
//    split: the edges on its right side are deleted and re-inserted on a new vertex at the same
//    place (delete_edge, create_vertex, insert_edge only). Inside the surface this opens one new
//    boundary loop (a labelled face); from the boundary it notches the boundary loop; from
//    boundary to boundary it separates a part.
// 3. The body's springs, masses and triangles are rebuilt from the new topology (its version
//    moved, so the BVH rebuilds too); new vertices copy the state of the vertex they split from.

#include <cstddef>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/polygon_export.h"
#include "bisturi/sim/collision.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

struct CutOptions {
  /// Smallest distance, as a fraction of the face's mean edge length, between a face diagonal
  /// the path takes and any other corner of that face.
  double sliver_fraction = 0.25;
  /// Where the blade's tip was at each blade point (as many as the points; world, metres). With
  /// them an incision inside the surface is closed by two walls down to the tips' depth
  /// (CutResult::floor_vertices; faces marked kInteriorFaces): the wound is a notch in a closed
  /// solid. Without them the
  /// incision is left open (a labelled face).
  std::span<const glm::dvec3> blade_tips_m;
};

struct CutResult {
  std::vector<VertexId> path;          ///< the vertices the incision runs through, in order
  std::vector<VertexId> new_vertices;  ///< the far lip's copies of the opened path vertices
  std::size_t split_faces = 0;         ///< faces split by a diagonal of the path
  bool starts_on_boundary = false;
  bool ends_on_boundary = false;
  /// The floor of the wound's walls (CutOptions::blade_tips_m), one under each opened pair.
  std::vector<VertexId> floor_vertices;
};

/// Cuts `body` along the blade contact points (at least two, metres). Throws CutError (before
/// any change) when the points give no path with at least one vertex to open (too short, along
/// the boundary, or off the surface). After a cut, validate(body.mesh()) passes.
CutResult cut_surface(SoftBody& body, std::span<const glm::dvec3> points_m,
                      const CutOptions& options = {});

/// The blade edge (a segment) swept over a body: each sample adds the point where the edge
/// crosses the surface, if it does; finish() cuts along the samples.
class ScalpelSweep {
 public:
  /// Returns true when the blade edge crosses the surface at this sample.
  bool sample(const SoftBody& body, const SurfaceBvh& bvh, const glm::dvec3& edge_from_m,
              const glm::dvec3& edge_to_m);
  [[nodiscard]] const std::vector<glm::dvec3>& points() const { return points_; }
  /// Cuts along the samples (CutError when fewer than two) and clears them.
  CutResult finish(SoftBody& body, const CutOptions& options = {});

 private:
  std::vector<glm::dvec3> points_;
};

}  // namespace bisturi::sim
