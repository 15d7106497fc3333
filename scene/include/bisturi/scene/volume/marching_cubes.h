#pragma once
// Isosurfaces of sampled volumes, straight into the DLFL: marching cubes with the face
// ambiguities resolved by the asymptotic decider.
//
// Inside and outside. A sample is inside when its value is strictly greater than the iso value;
// a sample equal to the iso value (and NaN) is outside. A grid edge is crossed when its two samples
// differ; its one vertex is placed by linear interpolation (or, on request, where the cubic through
// the four samples on the edge's grid line crosses the iso value: VertexPlacement::Cubic) and kept
// strictly inside the edge (parameter clamped to [1e-3, 1 - 1e-3]), so no two vertices coincide
// and no edge has zero length even where samples equal the iso value.
//
// Topology. Each cell joins its edge crossings into segments on its six faces and chains them
// into closed polygons (no published case table is copied: the 256 configurations are derived at
// start-up, see scene/src/surface/cube_cases.cpp). A face with two diagonal inside corners is
// ambiguous; the asymptotic decider (the value of the bilinear interpolant at its saddle, compared
// with the iso value) decides whether the inside corners are joined across the face. It only
// reads the face's four samples, so both cells of a face decide alike: the surface is watertight.
// The interior ambiguity of a cell (a tunnel between two opposite corners) is not reconstructed;
// the cell takes the configuration its faces imply. Guarantees: every vertex lies on one crossed
// grid edge (or is the centroid of a cell polygon that has no admissible diagonal triangulation);
// the triangles form a consistently oriented 2-manifold whose parts are closed except where they
// reach the volume's outermost samples; two objects whose inside samples are not face-connected
// through the decider stay separate parts.
//
// Orientation. Triangles are counter-clockwise seen from outside (value <= iso), in the world
// frame: when the index-to-world map reverses orientation (det(direction) < 0) the winding is
// flipped, so normals point from inside to outside in world millimetres and the enclosed volume
// of a closed part is positive. A hollow object's inner shell encloses negative volume.

#include <cstddef>
#include <cstdint>
#include <functional>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

class BonoOctree;

/// Where a vertex goes on its crossed grid edge (samples f1 at parameter 0 and f2 at 1).
enum class VertexPlacement : std::uint8_t {
  /// The root of the straight line through f1 and f2 (classic marching cubes). Exact for a field
  /// that is linear along the edge; on a smooth field the vertex sits off the true isosurface by
  /// about h^2 |f''| / (8 |f'|) (h: the spacing).
  Linear,
  /// The root in [0, 1] of the cubic through the four samples f0, f1, f2, f3 of the edge's grid
  /// line at parameters -1, 0, 1, 2 (a quadratic through three where the edge touches the
  /// volume's border), found by Newton steps kept inside the bracket (bisection when a step
  /// leaves it). Exact for fields cubic along the grid lines; on a smooth field the error falls
  /// to O(h^4), so vertices lie on the true isosurface to a small fraction of a voxel (the test
  /// phantoms: below 1e-4 mm at 0.5 mm spacing, against about 3e-3 mm for Linear). Costs two
  /// more sample reads and a few polynomial evaluations per vertex.
  Cubic,
};

struct IsoSurfaceOptions {
  /// Inside: value > iso.
  float iso = 0.0f;
  /// Called with (done, total) slabs of cells during extraction, about every 1% of the slabs.
  std::function<void(std::size_t, std::size_t)> progress;
  /// Called with (done, total) edges written during the DLFL build (extract_isosurface only).
  std::function<void(std::size_t, std::size_t)> build_progress;
  /// Empty-space skipping: only cells of leaves whose value range contains iso are visited.
  /// Must be built from the same grid. When null, one is built if build_octree is set.
  const BonoOctree* octree = nullptr;
  /// Build an octree (leaf_size 8) when none is given. Building one reads every sample once, as
  /// the classification does, so for a single extraction it rarely pays; reuse one across iso
  /// values instead.
  bool build_octree = false;
  /// Vertex placement on crossed edges; the topology (cases, decider) is the same for both.
  VertexPlacement placement = VertexPlacement::Linear;
};

struct ExtractionStats {
  std::size_t cells = 0;          ///< cells of the volume (product of dims - 1)
  std::size_t cells_visited = 0;  ///< mixed cells, each of which produced polygons
  std::size_t leaves_visited = 0;
  std::size_t leaves_skipped = 0;
  std::size_t ambiguous_faces = 0;  ///< decider evaluations (each shared face counted per cell)
  std::size_t vertices = 0;
  std::size_t centroid_vertices = 0;  ///< extra vertices (polygons without admissible diagonals)
  std::size_t triangles = 0;
  double octree_seconds = 0.0;
  double extract_seconds = 0.0;  ///< classification and vertex placement (and the mesh's triangles)
  double build_seconds = 0.0;    ///< writing the DLFL records (extract_isosurface only)
};

/// The isosurface as indexed triangles (world millimetres), vertices shared through the grid
/// edges they lie on. Throws InputError when values and dims disagree, the iso value is not
/// finite, a spacing is not positive, the direction is singular, or the surface needs more than
/// 2^32 - 1 vertices or indices. A volume with fewer than two samples along an axis gives an
/// empty mesh.
PolygonMesh extract_isosurface_mesh(const Grid<float>& volume,
                                    const IsoSurfaceOptions& options = {},
                                    ExtractionStats* stats = nullptr);

/// The isosurface as a Dlfl: the structure build_oriented_manifold makes from the triangles of
/// extract_isosurface_mesh (vertex v and triangle t keep their indices, as vertex v and face t),
/// written directly from the cell tables in a second pass over the kept classification, with
/// every array sized exactly. Every part that reaches the volume's border is open, and each of
/// its boundary loops is a labelled (bounding) face, after the triangles.
Dlfl extract_isosurface(const Grid<float>& volume, const IsoSurfaceOptions& options = {},
                        ExtractionStats* stats = nullptr);

}  // namespace bisturi
