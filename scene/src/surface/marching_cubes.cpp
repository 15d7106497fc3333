#include "bisturi/scene/volume/marching_cubes.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstring>
#include <functional>
#include <limits>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/bono_octree.h"
#include "construction/raw_arrays.h"
#include "surface/cube_cases.h"
#include "surface/extraction_sinks.h"

// The extraction runs slab by slab (cells between sample planes k and k+1), in the manner of
// flying edges:
//  - each sample plane is classified once into bit rows (bit i of row j: sample (i, j) inside);
//  - a vertex is made for every crossed x- and y-edge of a plane and every crossed z-edge of a
//    slab, and its index stored in per-plane arrays indexed by the edge's lower sample (two
//    planes of x/y ids and one slab of z ids live at a time);
//  - mixed cells are found 64 at a time with bit operations on the four rows of a cell row, and
//    each emits the triangles of its case, looking vertices up by cube edge.
// With an octree, only the cell rows (and x-ranges) covered by leaves whose range contains the
// iso value are visited, and only the sample words those cells touch are classified.
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

using surface::CellIds;
using surface::CountSink;
using surface::DlflSink;
using surface::kNoVertex;
using surface::MeshSink;

using Clock = std::chrono::steady_clock;
constexpr double kEdgeEps = 1e-3;

double seconds_since(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

/// Bits [lo, hi) of word w (sample indices), hi > lo allowed to fall outside the word.
std::uint64_t range_mask(std::int64_t w, std::int64_t lo, std::int64_t hi) {
  const std::int64_t base = 64 * w;
  const std::int64_t a = std::clamp<std::int64_t>(lo - base, 0, 64);
  const std::int64_t b = std::clamp<std::int64_t>(hi - base, 0, 64);
  if (b <= a) return 0;
  const std::uint64_t upper = b == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << b) - 1;
  const std::uint64_t lower = (std::uint64_t{1} << a) - 1;
  return upper & ~lower;
}

/// An interval of indices [lo, hi); empty when lo >= hi.
struct Span {
  std::int32_t lo = 0;
  std::int32_t hi = 0;
  [[nodiscard]] bool empty() const { return lo >= hi; }
  void unite(Span o) {
    if (o.empty()) return;
    if (empty()) {
      *this = o;
    } else {
      lo = std::min(lo, o.lo);
      hi = std::max(hi, o.hi);
    }
  }
  [[nodiscard]] Span intersect(Span o) const { return {std::max(lo, o.lo), std::min(hi, o.hi)}; }
};

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

class Extractor {
 public:
  Extractor(const Grid<float>& volume, const IsoSurfaceOptions& options, ExtractionStats& stats)
      : values_(volume.values.data()),
        geometry_(volume.geometry),
        iso_(options.iso),
        options_(options),
        stats_(stats),
        cases_(surface::cube_cases()) {
    nx_ = geometry_.dims[0];
    ny_ = geometry_.dims[1];
    nz_ = geometry_.dims[2];
    words_ = (nx_ + 63) / 64;
    row_stride_ = words_ + 1;  // one zero word of padding: reading word w + 1 is always valid
    plane_ = nx_ * ny_;
    for (int a = 0; a < 3; ++a) {
      axes_[static_cast<std::size_t>(a)] = geometry_.direction[a] * geometry_.spacing[a];
    }
    flip_ = glm::determinant(geometry_.direction) < 0.0;
    for (int c = 0; c < 8; ++c) {
      corner_offset_[static_cast<std::size_t>(c)] =
          (c & 1) + nx_ * ((c >> 1) & 1) + plane_ * ((c >> 2) & 1);
    }
  }

  /// Restricts the visited cells to the leaves of `octree` whose range holds the iso value.
  void skip_with(const BonoOctree* octree) {
    if (octree == nullptr) return;
    cell_rows_.assign(static_cast<std::size_t>((ny_ - 1) * (nz_ - 1)), Span{});
    std::size_t visited = 0;
    octree->for_each_leaf_in_range(iso_, iso_, [&](const BonoOctree::Node& n) {
      ++visited;
      const auto& o = n.box.origin;
      const auto& s = n.box.size;
      const Span xs{static_cast<std::int32_t>(o[0]),
                    static_cast<std::int32_t>(std::min(o[0] + s[0], nx_ - 1))};
      if (xs.empty()) return;
      const std::int64_t j1 = std::min(o[1] + s[1], ny_ - 1);
      const std::int64_t k1 = std::min(o[2] + s[2], nz_ - 1);
      for (std::int64_t k = o[2]; k < k1; ++k) {
        for (std::int64_t j = o[1]; j < j1; ++j) {
          cell_rows_[static_cast<std::size_t>(k * (ny_ - 1) + j)].unite(xs);
        }
      }
    });
    stats_.leaves_visited = visited;
    stats_.leaves_skipped = octree->leaf_count() - visited;
  }

  /// One pass: planes are classified as the slabs advance (two kept at a time).
  void mesh(PolygonMesh& mesh) {
    allocate_planes(2);
    MeshSink sink(mesh, flip_);
    classify_plane(0);
    write_slabs(sink, true, options_.progress);
  }

  /// Two passes. The first classifies every plane (kept, one bit per sample), places the vertices
  /// and counts; the second writes the records into arrays of the exact final sizes, from the
  /// kept bits (the volume is read again only by the decider).
  void dlfl(Dlfl& d) {
    allocate_planes(nz_);
    CountSink counter(cases_, nx_ - 1, ny_ - 1, nz_ - 1);
    classify_plane(0);
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
  [[nodiscard]] Span cell_row(std::int64_t j, std::int64_t k) const {
    if (j < 0 || k < 0 || j >= ny_ - 1 || k >= nz_ - 1) return {};
    if (cell_rows_.empty()) return {0, static_cast<std::int32_t>(nx_ - 1)};
    return cell_rows_[static_cast<std::size_t>(k * (ny_ - 1) + j)];
  }

  /// Samples a sample row must have classified: those of the cell rows around it (+1 in x).
  [[nodiscard]] Span sample_row(std::int64_t j, std::int64_t z) const {
    Span s;
    for (std::int64_t dj = -1; dj <= 0; ++dj) {
      for (std::int64_t dz = -1; dz <= 0; ++dz)
        s.unite(cell_row(j + dj, z + dz));
    }
    if (!s.empty()) s.hi += 1;
    return s;
  }

  void allocate_planes(std::int64_t kept) {
    planes_kept_ = kept;
    bits_.assign(static_cast<std::size_t>(kept * ny_ * row_stride_), 0);
    fresh_.assign(static_cast<std::size_t>(kept * ny_), Span{});
    for (auto& v : xid_)
      v.assign(static_cast<std::size_t>(plane_), kNoVertex);
    for (auto& v : yid_)
      v.assign(static_cast<std::size_t>(plane_), kNoVertex);
    zid_.assign(static_cast<std::size_t>(plane_), kNoVertex);
  }

  [[nodiscard]] std::uint64_t* bits(std::int64_t z) {
    return bits_.data() + (z % planes_kept_) * ny_ * row_stride_;
  }
  [[nodiscard]] Span* fresh(std::int64_t z) { return fresh_.data() + (z % planes_kept_) * ny_; }

  /// The slabs in order: vertices of each new plane and slab, then the cells' triangles.
  template <class Sink>
  void write_slabs(Sink& sink, bool classify,
                   const std::function<void(std::size_t, std::size_t)>& progress) {
    const std::size_t slabs = static_cast<std::size_t>(nz_ - 1);
    const std::size_t step = std::max<std::size_t>(1, slabs / 100);
    plane_vertices(0, sink);
    for (std::int64_t k = 0; k + 1 < nz_; ++k) {
      if (classify) classify_plane(k + 1);
      plane_vertices(k + 1, sink);
      slab_vertices(k, sink);
      for (std::int64_t j = 0; j + 1 < ny_; ++j) {
        const Span cells = cell_row(j, k);
        if (cells.empty()) continue;
        for_each_mixed_cell(j, k, cells, [&](unsigned config, std::int64_t i) {
          if constexpr (Sink::kStats) ++stats_.cells_visited;
          emit_cell(config, i, j, k, sink);
        });
      }
      const auto done = static_cast<std::size_t>(k + 1);
      if (progress && (done % step == 0 || done == slabs)) progress(done, slabs);
    }
  }

  void classify_plane(std::int64_t z) {
    std::uint64_t* plane_bits = bits(z);
    Span* plane_fresh = fresh(z);
    for (std::int64_t j = 0; j < ny_; ++j) {
      const Span s = sample_row(j, z);
      std::uint64_t* row = plane_bits + j * row_stride_;
      if (s.empty()) {
        plane_fresh[j] = {};
        continue;
      }
      const std::int64_t w0 = s.lo / 64, w1 = (std::min<std::int64_t>(s.hi, nx_) + 63) / 64;
      plane_fresh[j] = {static_cast<std::int32_t>(64 * w0),
                        static_cast<std::int32_t>(std::min<std::int64_t>(64 * w1, nx_))};
      const float* v = values_ + z * plane_ + j * nx_;
      for (std::int64_t w = w0; w < w1; ++w) {
        const std::int64_t i0 = 64 * w;
        const std::int64_t n = std::min<std::int64_t>(64, nx_ - i0);
        row[w] = n == 64 ? classify64(v + i0) : classify_tail(v + i0, n);
      }
    }
  }

  [[nodiscard]] std::uint64_t classify64(const float* v) const {
    std::array<std::uint8_t, 64> flags;
    const float iso = iso_;
    for (std::size_t b = 0; b < 64; ++b)
      flags[b] = static_cast<std::uint8_t>(v[b] > iso);
    std::uint64_t word = 0;
    for (std::size_t g = 0; g < 8; ++g) {
      std::uint64_t eight;
      std::memcpy(&eight, flags.data() + 8 * g, 8);
      // Gathers the low bit of each byte into the top byte (little-endian byte order).
      word |= ((eight * 0x0102040810204080ULL) >> 56) << (8 * g);
    }
    return word;
  }

  [[nodiscard]] std::uint64_t classify_tail(const float* v, std::int64_t n) const {
    std::uint64_t word = 0;
    for (std::int64_t b = 0; b < n; ++b) {
      word |= static_cast<std::uint64_t>(v[b] > iso_ ? 1 : 0) << b;
    }
    return word;
  }

  [[nodiscard]] glm::dvec3 world(double i, double j, double k) const {
    return geometry_.origin + axes_[0] * i + axes_[1] * j + axes_[2] * k;
  }

  [[nodiscard]] double edge_parameter(float a, float b) const {
    const double t = (double(iso_) - double(a)) / (double(b) - double(a));
    if (!(t >= kEdgeEps)) return std::isfinite(t) && t < kEdgeEps ? kEdgeEps : 0.5;
    return std::min(t, 1.0 - kEdgeEps);
  }

  /// The parameter of the crossed edge from sample p[0] to p[stride]; `index` is p's index along
  /// the edge's axis, `n` the samples along it (for the outer samples of the cubic).
  [[nodiscard]] double edge_parameter(const float* p, std::int64_t stride, std::int64_t index,
                                      std::int64_t n) const {
    const double linear = edge_parameter(p[0], p[stride]);
    if (options_.placement == VertexPlacement::Linear) return linear;
    const double iso = double(iso_);
    const double g1 = double(p[0]) - iso, g2 = double(p[stride]) - iso;
    const bool has0 = index > 0, has3 = index + 2 < n;
    double g0 = has0 ? double(p[-stride]) - iso : 0.0;
    double g3 = has3 ? double(p[2 * stride]) - iso : 0.0;
    if (!std::isfinite(g1) || !std::isfinite(g2) || !std::isfinite(g0) || !std::isfinite(g3)) {
      return linear;
    }
    // p(t) = a + b t + c t^2 + d t^3 through the available samples.
    double b = 0.0, c = 0.0, d = 0.0;
    if (has0 && has3) {
      b = -g0 / 3.0 - g1 / 2.0 + g2 - g3 / 6.0;
      c = (g0 + g2) / 2.0 - g1;
      d = (g3 - g0) / 6.0 + (g1 - g2) / 2.0;
    } else if (has3) {
      b = (-3.0 * g1 + 4.0 * g2 - g3) / 2.0;
      c = (g1 - 2.0 * g2 + g3) / 2.0;
    } else if (has0) {
      b = (g2 - g0) / 2.0;
      c = (g0 + g2) / 2.0 - g1;
    } else {
      return linear;
    }
    const auto value = [&](double t) { return g1 + t * (b + t * (c + t * d)); };
    // Bracket [lo, hi] with value(lo) on g1's side (<= 0 is outside, as the classification).
    double lo = 0.0, hi = 1.0;
    const bool rising = g1 <= 0.0;
    double t = std::clamp(linear, 0.0, 1.0);
    for (int it = 0; it < 40; ++it) {
      const double v = value(t);
      if (v == 0.0) break;
      if ((v < 0.0) == rising) {
        lo = t;
      } else {
        hi = t;
      }
      const double slope = b + t * (2.0 * c + t * 3.0 * d);
      double next = slope != 0.0 ? t - v / slope : 0.5 * (lo + hi);
      if (!(next > std::min(lo, hi) && next < std::max(lo, hi))) next = 0.5 * (lo + hi);
      if (std::abs(next - t) < 1e-13) {
        t = next;
        break;
      }
      t = next;
    }
    return std::clamp(t, kEdgeEps, 1.0 - kEdgeEps);
  }

  /// Calls fn(axis, j, w, crossed) for each word of crossed x-edges (axis 0, samples (i, i+1) of
  /// row j) and y-edges (axis 1, rows j and j+1) of sample plane z.
  template <class Fn>
  void plane_crossings(std::int64_t z, Fn&& fn) {
    const std::uint64_t* plane_bits = bits(z);
    const Span* plane_fresh = fresh(z);
    for (std::int64_t j = 0; j < ny_; ++j) {
      const std::uint64_t* row = plane_bits + j * row_stride_;
      // x-edges (i, i+1): both samples classified.
      const Span xs{plane_fresh[j].lo, plane_fresh[j].hi - 1};
      if (!xs.empty()) {
        for (std::int64_t w = xs.lo / 64; w * 64 < xs.hi; ++w) {
          fn(0, j, w,
             (row[w] ^ ((row[w] >> 1) | (row[w + 1] << 63))) & range_mask(w, xs.lo, xs.hi));
        }
      }
      if (j + 1 >= ny_) continue;
      const Span ys = plane_fresh[j].intersect(plane_fresh[j + 1]);
      if (ys.empty()) continue;
      const std::uint64_t* up = row + row_stride_;
      for (std::int64_t w = ys.lo / 64; w * 64 < ys.hi; ++w) {
        fn(1, j, w, (row[w] ^ up[w]) & range_mask(w, ys.lo, ys.hi));
      }
    }
  }

  /// Calls fn(j, w, crossed) for each word of crossed z-edges between planes k and k + 1.
  template <class Fn>
  void slab_crossings(std::int64_t k, Fn&& fn) {
    const std::uint64_t* b0 = bits(k);
    const std::uint64_t* b1 = bits(k + 1);
    const Span* f0 = fresh(k);
    const Span* f1 = fresh(k + 1);
    for (std::int64_t j = 0; j < ny_; ++j) {
      const Span zs = f0[j].intersect(f1[j]);
      if (zs.empty()) continue;
      const std::uint64_t* r0 = b0 + j * row_stride_;
      const std::uint64_t* r1 = b1 + j * row_stride_;
      for (std::int64_t w = zs.lo / 64; w * 64 < zs.hi; ++w) {
        fn(j, w, (r0[w] ^ r1[w]) & range_mask(w, zs.lo, zs.hi));
      }
    }
  }

  /// Vertices of the crossed x- and y-edges of sample plane z.
  template <class Sink>
  void plane_vertices(std::int64_t z, Sink& sink) {
    std::uint32_t* xid = xid_[static_cast<std::size_t>(z & 1)].data();
    std::uint32_t* yid = yid_[static_cast<std::size_t>(z & 1)].data();
    const float* vz = values_ + z * plane_;
    plane_crossings(z, [&](int axis, std::int64_t j, std::int64_t w, std::uint64_t cross) {
      const float* v = vz + j * nx_;
      while (cross != 0) {
        const std::int64_t i = 64 * w + __builtin_ctzll(cross);
        cross &= cross - 1;
        if constexpr (!Sink::kPlaces) {
          (axis == 0 ? xid : yid)[j * nx_ + i] = sink.vertex();
        } else if (axis == 0) {
          const double t = edge_parameter(v + i, 1, i, nx_);
          xid[j * nx_ + i] = sink.vertex(world(double(i) + t, double(j), double(z)));
        } else {
          const double t = edge_parameter(v + i, nx_, j, ny_);
          yid[j * nx_ + i] = sink.vertex(world(double(i), double(j) + t, double(z)));
        }
      }
    });
  }

  /// Vertices of the crossed z-edges between planes k and k + 1.
  template <class Sink>
  void slab_vertices(std::int64_t k, Sink& sink) {
    const float* vk = values_ + k * plane_;
    slab_crossings(k, [&](std::int64_t j, std::int64_t w, std::uint64_t cross) {
      const float* v = vk + j * nx_;
      while (cross != 0) {
        const std::int64_t i = 64 * w + __builtin_ctzll(cross);
        cross &= cross - 1;
        std::uint32_t& id = zid_[static_cast<std::size_t>(j * nx_ + i)];
        if constexpr (Sink::kPlaces) {
          const double t = edge_parameter(v + i, plane_, k, nz_);
          id = sink.vertex(world(double(i), double(j), double(k) + t));
        } else {
          (void)v;
          id = sink.vertex();
        }
      }
    });
  }

  /// Calls fn(config, i) for the mixed cells [cells.lo, cells.hi) of cell row (j, k), in order.
  template <class Fn>
  void for_each_mixed_cell(std::int64_t j, std::int64_t k, Span cells, Fn&& fn) {
    const std::uint64_t* r00 = bits(k) + j * row_stride_;
    const std::uint64_t* r10 = r00 + row_stride_;
    const std::uint64_t* r01 = bits(k + 1) + j * row_stride_;
    const std::uint64_t* r11 = r01 + row_stride_;
    for (std::int64_t w = cells.lo / 64; w * 64 < cells.hi; ++w) {
      const std::uint64_t a00 = r00[w], a10 = r10[w], a01 = r01[w], a11 = r11[w];
      const std::uint64_t s00 = (a00 >> 1) | (r00[w + 1] << 63);
      const std::uint64_t s10 = (a10 >> 1) | (r10[w + 1] << 63);
      const std::uint64_t s01 = (a01 >> 1) | (r01[w + 1] << 63);
      const std::uint64_t s11 = (a11 >> 1) | (r11[w + 1] << 63);
      const std::uint64_t any = a00 | a10 | a01 | a11 | s00 | s10 | s01 | s11;
      const std::uint64_t all = a00 & a10 & a01 & a11 & s00 & s10 & s01 & s11;
      std::uint64_t mixed = any & ~all & range_mask(w, cells.lo, cells.hi);
      while (mixed != 0) {
        const int b = __builtin_ctzll(mixed);
        mixed &= mixed - 1;
        const auto config = static_cast<unsigned>(
            ((a00 >> b) & 1) | (((s00 >> b) & 1) << 1) | (((a10 >> b) & 1) << 2) |
            (((s10 >> b) & 1) << 3) | (((a01 >> b) & 1) << 4) | (((s01 >> b) & 1) << 5) |
            (((a11 >> b) & 1) << 6) | (((s11 >> b) & 1) << 7));
        fn(config, 64 * w + b);
      }
    }
  }

  /// The case entry of cell (i, j, k): the asymptotic decider settles its ambiguous faces.
  std::uint32_t entry_index(unsigned config, std::int64_t i, std::int64_t j, std::int64_t k,
                            std::size_t* ambiguous) const {
    const surface::CubeCase& cc = cases_.cases[config];
    unsigned outcome = 0;
    if (cc.ambiguous_count != 0) {
      const float* base = values_ + k * plane_ + j * nx_ + i;
      unsigned bit = 0;
      for (std::size_t f = 0; f < 6; ++f) {
        if (!((cc.ambiguous_faces >> f) & 1)) continue;
        const auto& q = cases_.faces[f].corners;
        const double d0 = double(base[corner_offset_[q[0]]]) - double(iso_);
        const double d1 = double(base[corner_offset_[q[1]]]) - double(iso_);
        const double d2 = double(base[corner_offset_[q[2]]]) - double(iso_);
        const double d3 = double(base[corner_offset_[q[3]]]) - double(iso_);
        // The inside corners are joined across the face when the bilinear saddle is inside:
        // (product of the inside pair) > (product of the outside pair), both pairs shifted by iso.
        const bool q0_inside = ((config >> q[0]) & 1) != 0;
        const double inside_product = q0_inside ? d0 * d2 : d1 * d3;
        const double outside_product = q0_inside ? d1 * d3 : d0 * d2;
        if (inside_product > outside_product) outcome |= 1u << bit;
        ++bit;
      }
      if (ambiguous != nullptr) *ambiguous += bit;
    }
    return cc.first_entry + outcome;
  }

  template <class Sink>
  void emit_cell(unsigned config, std::int64_t i, std::int64_t j, std::int64_t k, Sink& sink) {
    const std::int64_t x = nx_;
    const std::size_t p0 = static_cast<std::size_t>(k & 1), p1 = 1 - p0;
    const std::uint32_t* x0 = xid_[p0].data() + j * x;
    const std::uint32_t* x1 = xid_[p1].data() + j * x;
    const std::uint32_t* y0 = yid_[p0].data() + j * x;
    const std::uint32_t* y1 = yid_[p1].data() + j * x;
    const std::uint32_t* zz = zid_.data() + j * x;
    CellIds ids;
    ids[0] = x0[i];
    ids[1] = x0[i + x];
    ids[2] = x1[i];
    ids[3] = x1[i + x];
    ids[4] = y0[i];
    ids[5] = y0[i + 1];
    ids[6] = y1[i];
    ids[7] = y1[i + 1];
    ids[8] = zz[i];
    ids[9] = zz[i + 1];
    ids[10] = zz[i + x];
    ids[11] = zz[i + x + 1];
    const std::uint32_t e =
        entry_index(config, i, j, k, Sink::kStats ? &stats_.ambiguous_faces : nullptr);
    const surface::CaseEntry& entry = cases_.entries[e];
    for (std::uint32_t n = 0; n < entry.extra_count; ++n) {
      if constexpr (Sink::kPlaces) {
        const surface::ExtraVertex& ev = cases_.extras[entry.first_extra + n];
        glm::dvec3 sum(0.0);
        for (std::uint32_t c = 0; c < ev.code_count; ++c) {
          sum += sink.position(ids[cases_.extra_codes[ev.first_code + c]]);
        }
        // The centroid, in world coordinates already.
        ids[12 + n] = sink.vertex(sum / double(ev.code_count));
      } else {
        ids[12 + n] = sink.vertex();
      }
      if constexpr (Sink::kStats) ++stats_.centroid_vertices;
    }
    sink.triangles(cases_, entry, ids, i, j, k);
  }

  const float* values_;
  const VolumeGeometry& geometry_;
  float iso_;
  const IsoSurfaceOptions& options_;
  ExtractionStats& stats_;
  const surface::CubeCases& cases_;
  std::int64_t nx_ = 0, ny_ = 0, nz_ = 0, words_ = 0, row_stride_ = 0, plane_ = 0;
  std::int64_t planes_kept_ = 2;
  std::array<glm::dvec3, 3> axes_{};
  bool flip_ = false;
  std::array<std::int64_t, 8> corner_offset_{};
  std::vector<Span> cell_rows_;        // empty: every cell row is visited whole
  ScratchVector<std::uint64_t> bits_;  // per kept plane: rows of classification bits
  ScratchVector<Span> fresh_;          // per kept plane and sample row: the classified samples
  // Vertex ids of the crossed edges by lower sample: x and y of two planes, z of one slab.
  std::array<ScratchVector<std::uint32_t>, 2> xid_, yid_;
  ScratchVector<std::uint32_t> zid_;
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
