#include "bisturi/scene/volume/marching_cubes.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/bono_octree.h"
#include "construction/raw_arrays.h"
#include "surface/cell_emitter.h"
#include "surface/crossing_walks.h"
#include "surface/cube_cases.h"
#include "surface/edge_placement.h"
#include "surface/edge_vertices.h"
#include "surface/elapsed.h"
#include "surface/extraction_sinks.h"
#include "surface/index_span.h"
#include "surface/sign_planes.h"
#include "surface/visited_cells.h"

// The extraction runs slab by slab (cells between sample planes k and k+1), in the manner of
// flying edges:
//  - each sample plane is classified once into bit rows (bit i of row j: sample (i, j) inside;
//    SignPlanes, sign_planes.h);
//  - a vertex is made for every crossed x- and y-edge of a plane and every crossed z-edge of a
//    slab, and its index stored in per-plane arrays indexed by the edge's lower sample (two
//    planes of x/y ids and one slab of z ids live at a time; EdgeVertices, edge_vertices.h,
//    placed by EdgePlacement, edge_placement.h);
//  - mixed cells are found 64 at a time with bit operations on the four rows of a cell row
//    (crossing_walks.h), and each emits the triangles of its case, looking vertices up by cube
//    edge (CellEmitter, cell_emitter.h).
// With an octree, only the cell rows (and x-ranges) covered by leaves whose range contains the
// iso value are visited, and only the sample words those cells touch are classified
// (VisitedCells, visited_cells.h).
//
// The DLFL is written directly, in two passes over the slabs. The first classifies every plane
// (the bits are kept: one bit per sample), places the vertices and counts triangles and border
// sides; the Dlfl's arrays are then sized exactly and the second pass writes every record once
// from the kept bits: triangle t is face t with corners 3t..3t+2, and each side finds its twin
// from the cell tables, inside its cell or in a slot left by the neighbour across the cube face
// (DlflSink, extraction_sinks.h). No rotation-system sort, no triangle mesh in between; the
// result is the structure build_oriented_manifold makes from extract_isosurface_mesh's
// triangles.

namespace bisturi {
namespace {

using surface::CellEmitter;
using surface::CellIds;
using surface::CountSink;
using surface::DlflSink;
using surface::EdgePlacement;
using surface::EdgeVertices;
using surface::kNoVertex;
using surface::MeshSink;
using surface::SignPlanes;
using surface::Span;
using surface::VisitedCells;

using Clock = std::chrono::steady_clock;

using surface::seconds_since;

void check_input(const Grid<float>& volume, const IsoSurfaceOptions& options) {
  const VolumeGeometry& g = volume.geometry;
  for (int a = 0; a < 3; ++a) {
    if (g.dims[static_cast<std::size_t>(a)] < 1) {
      throw InputError("extract_isosurface: dimension " + std::to_string(a) + " is " +
                       std::to_string(g.dims[static_cast<std::size_t>(a)]) + " (must be >= 1)");
    }
    if (!(g.spacing[a] > 0.0) || !std::isfinite(g.spacing[a])) {
      throw InputError("extract_isosurface: spacing " + std::to_string(a) + " is " +
                       std::to_string(g.spacing[a]) + " (must be positive)");
    }
  }
  if (volume.values.size() != g.voxel_count()) {
    throw InputError("extract_isosurface: " + std::to_string(volume.values.size()) +
                     " values for dims " + std::to_string(g.dims[0]) + "x" +
                     std::to_string(g.dims[1]) + "x" + std::to_string(g.dims[2]));
  }
  if (g.dims[0] > std::numeric_limits<std::int32_t>::max() / 2 ||
      g.dims[1] > std::numeric_limits<std::int32_t>::max() / 2 ||
      g.dims[2] > std::numeric_limits<std::int32_t>::max() / 2) {
    throw InputError("extract_isosurface: dimensions too large");
  }
  if (!std::isfinite(options.iso)) {
    throw InputError("extract_isosurface: the iso value is not finite");
  }
  const double det = glm::determinant(g.direction);
  if (!(std::abs(det) > 1e-12) || !std::isfinite(det)) {
    throw InputError("extract_isosurface: the direction matrix is singular");
  }
}

/// The octree that restricts the visited cells: the caller's, or one built into `own`.
const BonoOctree* octree_for(const Grid<float>& volume, const IsoSurfaceOptions& options,
                             ExtractionStats& st, std::optional<BonoOctree>& own) {
  const BonoOctree* octree = options.octree;
  if (octree == nullptr && options.build_octree) {
    const auto start = Clock::now();
    own = BonoOctree::build(volume, BonoOptions{8});
    octree = &*own;
    st.octree_seconds = seconds_since(start);
  }
  if (octree != nullptr && octree->dims() != volume.geometry.dims) {
    throw InputError("extract_isosurface: the octree was built for other dimensions");
  }
  return octree;
}

/// Runs the pieces (the headers above) slab by slab, into a triangle mesh or a Dlfl.
class Extractor {
 public:
  Extractor(const Grid<float>& volume, const IsoSurfaceOptions& options, ExtractionStats& stats)
      : options_(options),
        stats_(stats),
        cases_(surface::cube_cases()),
        nx_(volume.geometry.dims[0]),
        ny_(volume.geometry.dims[1]),
        nz_(volume.geometry.dims[2]),
        flip_(glm::determinant(volume.geometry.direction) < 0.0),
        visited_(volume.geometry.dims),
        planes_(volume, options.iso),
        placement_(volume, options),
        vertices_(volume, placement_),
        emitter_(volume, options.iso, cases_, stats) {}

  /// Restricts the visited cells to the leaves of `octree` whose range holds the iso value.
  void skip_with(const BonoOctree* octree) {
    if (octree == nullptr) return;
    visited_.restrict_to(*octree, options_.iso, stats_);
  }

  /// One pass: planes are classified as the slabs advance (two kept at a time).
  void mesh(PolygonMesh& mesh) {
    allocate(2);
    MeshSink sink(mesh, flip_);
    planes_.classify(0, visited_);
    write_slabs(sink, true, options_.progress);
  }

  /// Two passes. The first classifies every plane (kept, one bit per sample), places the vertices
  /// and counts; the second writes the records into arrays of the exact final sizes, from the
  /// kept bits (the volume is read again only by the decider).
  void dlfl(Dlfl& d) {
    allocate(nz_);
    CountSink counter(cases_, nx_ - 1, ny_ - 1, nz_ - 1);
    planes_.classify(0, visited_);
    write_slabs(counter, true, options_.progress);
    const std::size_t corners = 3 * counter.triangle_count() + counter.border_sides();
    if (corners >= kNoVertex) throw InputError("extract_isosurface: more than 2^32 - 1 corners");
    const auto build_start = Clock::now();
    const std::size_t nv = counter.positions().size();
    const std::size_t nt = counter.triangle_count();
    const construction::RawArrays::View out =
        construction::RawArrays::size_empty(d, std::move(counter.positions()), corners, nt,
                                            nt + counter.border_sides() / 2, corners / 2);
    DlflSink sink(out, flip_, nx_ - 1, ny_ - 1, nz_ - 1);
    const std::size_t edges = corners / 2;
    std::function<void(std::size_t, std::size_t)> progress;
    if (options_.build_progress) {
      progress = [&](std::size_t done, std::size_t slabs) {
        options_.build_progress(edges * done / slabs, edges);
      };
    }
    write_slabs(sink, false, progress);
    sink.close_holes(d);
    if (sink.vertex_count() != nv || sink.triangle_count() != nt ||
        sink.border_sides() != counter.border_sides() || sink.edge_count() != edges) {
      throw std::logic_error("extract_isosurface: the counting and writing passes disagree");
    }
    construction::RawArrays::finish(d);
    stats_.vertices = nv;
    stats_.triangles = nt;
    stats_.build_seconds = seconds_since(build_start);
  }

 private:
  void allocate(std::int64_t planes_kept) {
    planes_.allocate(planes_kept);
    vertices_.allocate();
  }

  /// The slabs in order: vertices of each new plane and slab, then the cells' triangles.
  /// `classify`: classify each upper plane first (else the kept bits of an earlier pass are read).
  /// Kept out of line, one copy per pass: when GCC 12 inlined both passes into dlfl(), the
  /// writing pass ran about 10% slower (extract_bench dlfl/gyroid256).
  template <class Sink>
  [[gnu::noinline]] void write_slabs(
      Sink& sink, bool classify, const std::function<void(std::size_t, std::size_t)>& progress) {
    const std::size_t slabs = static_cast<std::size_t>(nz_ - 1);
    const std::size_t step = std::max<std::size_t>(1, slabs / 100);
    vertices_.add_plane(0, planes_.plane(0), sink);
    for (std::int64_t k = 0; k + 1 < nz_; ++k) {
      if (classify) planes_.classify(k + 1, visited_);
      const SignPlanes::Plane lower = planes_.plane(k);
      const SignPlanes::Plane upper = planes_.plane(k + 1);
      vertices_.add_plane(k + 1, upper, sink);
      vertices_.add_slab(k, lower, upper, sink);
      for (std::int64_t j = 0; j + 1 < ny_; ++j) {
        const Span cells = visited_.cells(j, k);
        if (cells.empty()) continue;
        surface::for_each_mixed_cell(lower, upper, j, cells, [&](unsigned config, std::int64_t i) {
          if constexpr (Sink::kStats) ++stats_.cells_visited;
          CellIds ids;
          vertices_.cell_ids(i, j, k, ids);
          emitter_.emit(config, i, j, k, ids, sink);
        });
      }
      const auto done = static_cast<std::size_t>(k + 1);
      if (progress && (done % step == 0 || done == slabs)) progress(done, slabs);
    }
  }

  const IsoSurfaceOptions& options_;
  ExtractionStats& stats_;
  const surface::CubeCases& cases_;
  std::int64_t nx_, ny_, nz_;
  bool flip_;  // det(direction) < 0: the sinks reverse the winding
  VisitedCells visited_;
  SignPlanes planes_;
  EdgePlacement placement_;
  EdgeVertices vertices_;  // holds a reference to placement_, declared before it
  CellEmitter emitter_;
};

}  // namespace

PolygonMesh extract_isosurface_mesh(const Grid<float>& volume, const IsoSurfaceOptions& options,
                                    ExtractionStats* stats) {
  check_input(volume, options);
  ExtractionStats local;
  ExtractionStats& st = stats != nullptr ? *stats : local;
  st = ExtractionStats{};
  PolygonMesh mesh;
  const auto& d = volume.geometry.dims;
  if (d[0] < 2 || d[1] < 2 || d[2] < 2) return mesh;
  st.cells = static_cast<std::size_t>((d[0] - 1) * (d[1] - 1) * (d[2] - 1));
  std::optional<BonoOctree> own;
  const BonoOctree* octree = octree_for(volume, options, st, own);
  const auto start = Clock::now();
  Extractor extractor(volume, options, st);
  extractor.skip_with(octree);
  extractor.mesh(mesh);
  st.extract_seconds = seconds_since(start);
  st.vertices = mesh.positions.size();
  st.triangles = mesh.face_count();
  return mesh;
}

Dlfl extract_isosurface(const Grid<float>& volume, const IsoSurfaceOptions& options,
                        ExtractionStats* stats) {
  check_input(volume, options);
  ExtractionStats local;
  ExtractionStats& st = stats != nullptr ? *stats : local;
  st = ExtractionStats{};
  Dlfl dlfl;
  const auto& d = volume.geometry.dims;
  if (d[0] < 2 || d[1] < 2 || d[2] < 2) return dlfl;
  st.cells = static_cast<std::size_t>((d[0] - 1) * (d[1] - 1) * (d[2] - 1));
  std::optional<BonoOctree> own;
  const BonoOctree* octree = octree_for(volume, options, st, own);
  const auto start = Clock::now();
  Extractor extractor(volume, options, st);
  extractor.skip_with(octree);
  extractor.dlfl(dlfl);
  st.extract_seconds = seconds_since(start) - st.build_seconds;
  return dlfl;
}

}  // namespace bisturi
