#pragma once
// Decimation that keeps topology: quadric error metric (Garland–Heckbert) edge collapses on a
// triangle DLFL, in place, through the DLFL operators only.
//
// A collapse of v into u deletes the edges around v (its triangles merge into one polygon
// around it and v becomes a lone point sphere), deletes v, and re-triangulates the hole as a fan
// from u with insert_edge. The result is the usual half-edge collapse: the two triangles on the
// edge go, every other triangle of v gets u instead.
//
// What is kept:
// - Topology: a collapse is refused unless the link condition holds (u and v have exactly the
//   two opposite vertices in common, and those keep a valence of at least three), so genus,
//   number of parts and the number of boundary loops never change and no vertex is pinched.
// - Boundaries: vertices on a labelled (boundary) face are fixed, as are vertices of any other
//   non-triangular face; such a vertex may be the kept end of a collapse (at its own position)
//   but is never removed or moved, so every boundary loop keeps its vertices and edges exactly.
// - Non-manifold junctions: vertices with several rotations are fixed the same way, and a
//   collapse that would make an edge join one that lives in another rotation is refused.
// - Geometry: a collapse that would turn a face normal by more than acos(min_normal_cosine) (a
//   flip or a fold), leave a degenerate triangle or (optionally) a sliver is refused.
//
// The kept vertex goes to the point that minimises the summed quadric when that 3x3 system is
// well conditioned, else to the best of the two ends and the midpoint (a fixed end: its own
// position). Quadrics are the unweighted plane quadrics of the original faces, so the error of a
// collapse, sqrt(v^T Q v), bounds the distance of the new point to every original face plane
// merged into it (in the mesh's length unit).

#include <cstddef>
#include <functional>
#include <limits>

#include "bisturi/scene/dlfl.h"

namespace bisturi::lod {

struct DecimateOptions {
  /// Stop once at most this many faces (unlabelled faces with three or more corners) remain;
  /// 0: no face target.
  std::size_t target_faces = 0;
  /// Stop before the first collapse whose error exceeds this (length unit); infinity: no bound.
  double max_error = std::numeric_limits<double>::infinity();
  /// A collapse may not turn any face normal by more than acos(min_normal_cosine).
  double min_normal_cosine = 0.2;
  /// A collapse may not leave a face thinner than this (4 sqrt(3) area over the squared edges'
  /// sum: 1 equilateral, 0.17 ten times as long as wide) unless it was thinner before. The
  /// quadrics alone thin a straight tube to slivers its whole length long, which a simulated
  /// surface cannot bend along; 0: no bound (drawn levels).
  double min_triangle_quality = 0.0;
  /// Called with (collapses done, collapses needed for the face target or, without one, the
  /// most that could happen), about every 1% of the work and once at the end.
  std::function<void(std::size_t, std::size_t)> progress;
};

struct DecimateStats {
  std::size_t initial_faces = 0;
  std::size_t final_faces = 0;
  std::size_t collapses = 0;
  std::size_t rejected_topology = 0;  ///< refused by the link condition (genus, pinch, valence)
  std::size_t rejected_geometry = 0;  ///< refused for a flipped, folded or degenerate face
  std::size_t fixed_vertices = 0;     ///< boundary, junction or non-triangle vertices kept fixed
  double max_error = 0.0;             ///< largest error of a collapse that was done
  bool reached_target = false;        ///< stopped at the face target (not for want of collapses)
  bool stopped_by_error = false;      ///< stopped because the next collapse exceeded max_error
};

/// Decimates `mesh` in place. Faces must be triangles where vertices are to be removed (vertices
/// of other faces are fixed, see above). Removed elements go to the free lists; call
/// mesh.compact() afterwards for dense arrays. Handles of surviving vertices stay valid.
DecimateStats decimate(Dlfl& mesh, const DecimateOptions& options = {});

/// Number of unlabelled faces with three or more corners (the polygons export_polygons gives).
std::size_t polygon_face_count(const Dlfl& mesh);

}  // namespace bisturi::lod
