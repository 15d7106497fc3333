// Constrained windowed-sinc smoothing of marching-cubes label surfaces (see label_surface.h).

#include "bisturi/scene/volume/label_surface.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "label_caps.h"

namespace bisturi {

namespace {

using Vec3 = Dlfl::Vec3;
using Clock = std::chrono::steady_clock;

double seconds_since(Clock::time_point t) {
  return std::chrono::duration<double>(Clock::now() - t).count();
}

void check_options(const LabelSurfaceOptions& o) {
  if (o.iterations == 1 || !(o.pass_band > 0.0 && o.pass_band < 2.0)) {
    throw InputError("label surface: need iterations 0 or >= 2 and a pass band in (0, 2) (got " +
                     std::to_string(o.iterations) + ", " + std::to_string(o.pass_band) + ")");
  }
  if (!(o.twicing_share >= 0.0 && o.twicing_share <= 2.0 && o.twicing_share_flat >= 0.0 &&
        o.twicing_share_flat <= 2.0)) {
    throw InputError("label surface: need twicing shares in [0, 2] (got " +
                     std::to_string(o.twicing_share_flat) + " and " +
                     std::to_string(o.twicing_share) + ")");
  }
  if (!(o.twicing_bend_flat >= 0.0 && o.twicing_bend_sharp > o.twicing_bend_flat)) {
    throw InputError("label surface: need twicing bends 0 <= flat < sharp (got " +
                     std::to_string(o.twicing_bend_flat) + " and " +
                     std::to_string(o.twicing_bend_sharp) + ")");
  }
}

// Squared distances along one line of samples (spacing h) to the nearest feature sample (f = 0
// there, infinite elsewhere): the lower envelope of parabolas of Felzenszwalb and Huttenlocher
// ("Distance transforms of sampled functions", 2012), exact, linear in the line's length.
void distance_1d(const std::vector<double>& f, std::vector<double>& d, double h,
                 std::vector<std::size_t>& v, std::vector<double>& z) {
  const std::size_t n = f.size();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::size_t k = 0;
  std::size_t first = 0;
  while (first < n && f[first] == kInf)
    ++first;
  if (first == n) {
    std::fill(d.begin(), d.end(), kInf);
    return;
  }
  v[0] = first;
  z[0] = -kInf;
  z[1] = kInf;
  for (std::size_t q = first + 1; q < n; ++q) {
    if (f[q] == kInf) continue;
    const double xq = static_cast<double>(q) * h;
    for (;;) {
      const double xv = static_cast<double>(v[k]) * h;
      const double sx = ((f[q] + xq * xq) - (f[v[k]] + xv * xv)) / (2.0 * (xq - xv));
      if (sx <= z[k] && k > 0) {
        --k;
        continue;
      }
      ++k;
      v[k] = q;
      z[k] = sx;
      z[k + 1] = kInf;
      break;
    }
  }
  k = 0;
  for (std::size_t q = 0; q < n; ++q) {
    const double x = static_cast<double>(q) * h;
    while (z[k + 1] < x)
      ++k;
    const double dx = x - static_cast<double>(v[k]) * h;
    d[q] = dx * dx + f[v[k]];
  }
}

/// Distances (mm) within one slice, from every sample to the nearest whose mask value is `to`
/// (the slice holds some); scratch space kept between slices.
class SliceDistance {
 public:
  explicit SliceDistance(const VolumeGeometry& g)
      : nx_(static_cast<std::size_t>(g.dims[0])),
        ny_(static_cast<std::size_t>(g.dims[1])),
        hx_(g.spacing.x),
        hy_(g.spacing.y),
        f_(std::max(nx_, ny_)),
        d_(f_.size()),
        z_(f_.size() + 1),
        v_(f_.size()),
        plane_(nx_ * ny_) {}

  void operator()(const std::uint8_t* mask, std::uint8_t to, float* out) {
    constexpr double kInf = std::numeric_limits<double>::infinity();
    f_.resize(nx_);
    d_.resize(nx_);
    for (std::size_t j = 0; j < ny_; ++j) {
      for (std::size_t i = 0; i < nx_; ++i)
        f_[i] = mask[j * nx_ + i] == to ? 0.0 : kInf;
      distance_1d(f_, d_, hx_, v_, z_);
      std::copy(d_.begin(), d_.end(), plane_.begin() + static_cast<std::ptrdiff_t>(j * nx_));
    }
    f_.resize(ny_);
    d_.resize(ny_);
    for (std::size_t i = 0; i < nx_; ++i) {
      for (std::size_t j = 0; j < ny_; ++j)
        f_[j] = plane_[j * nx_ + i];
      distance_1d(f_, d_, hy_, v_, z_);
      for (std::size_t j = 0; j < ny_; ++j)
        out[j * nx_ + i] = static_cast<float>(std::sqrt(d_[j]));
    }
  }

 private:
  std::size_t nx_, ny_;
  double hx_, hy_;
  std::vector<double> f_, d_, z_;
  std::vector<std::size_t> v_;
  std::vector<double> plane_;
};

/// Each sample's signed in-slice distance (mm) to the outline of `mask`'s inside, positive
/// inside. A slice without inside (or outside) samples, or one `wanted` (if given) does not
/// hold, counts as one slice spacing away; slices of one kind (most of a map around a label)
/// are not transformed.
Grid<float> signed_slice_distances(std::span<const std::uint8_t> mask, const VolumeGeometry& g,
                                   const std::vector<std::uint8_t>* wanted) {
  Grid<float> field;
  field.geometry = g;
  field.values.resize(mask.size());
  if (std::find(mask.begin(), mask.end(), 1) == mask.end()) return field;
  const auto plane = static_cast<std::size_t>(g.dims[0] * g.dims[1]);
  const auto far = static_cast<float>(g.spacing.z);
  SliceDistance distance(g);
  std::vector<float> to_outside(plane), to_inside(plane);
  for (std::size_t k = 0; k < static_cast<std::size_t>(g.dims[2]); ++k) {
    const std::uint8_t* in = mask.data() + k * plane;
    float* out = field.values.data() + k * plane;
    const bool any_in = std::find(in, in + plane, 1) != in + plane;
    const bool any_out = std::find(in, in + plane, 0) != in + plane;
    if (!any_in || !any_out || (wanted != nullptr && (*wanted)[k] == 0)) {
      for (std::size_t i = 0; i < plane; ++i)
        out[i] = in[i] != 0 ? far : -far;
      continue;
    }
    distance(in, 0, to_outside.data());
    distance(in, 1, to_inside.data());
    for (std::size_t i = 0; i < plane; ++i)
      out[i] = in[i] != 0 ? to_outside[i] : -to_inside[i];
  }
  return field;
}

// A label map resampled from thicker slices by repeating them (CGAL's liver repeats every third
// slice) holds runs of identical slices: one original slice each, at the run's middle. Every
// slice of a run then gets the distances interpolated between its run's and the neighbouring
// run's, by position, as if the original slices had been interpolated; a run of one is kept.
void interpolate_repeated_slices(const std::vector<std::uint8_t>& mask, Grid<float>& field) {
  const VolumeGeometry& g = field.geometry;
  const std::size_t plane = static_cast<std::size_t>(g.dims[0] * g.dims[1]);
  const auto nz = static_cast<std::size_t>(g.dims[2]);
  struct Run {
    std::size_t first, last;
    double centre() const { return 0.5 * static_cast<double>(first + last); }
  };
  std::vector<Run> runs;
  std::size_t filled = 0, repeats = 0, longest = 1;
  for (std::size_t k = 0; k < nz; ++k) {
    const auto slice = mask.begin() + static_cast<std::ptrdiff_t>(k * plane);
    const bool empty = std::find(slice, slice + static_cast<std::ptrdiff_t>(plane), 1) ==
                       slice + static_cast<std::ptrdiff_t>(plane);
    filled += empty ? 0 : 1;
    // Empty slices are never repeats: a map has plenty above and below the label.
    const bool same = !empty && k > 0 && runs.back().last == k - 1 &&
                      std::equal(slice, slice + static_cast<std::ptrdiff_t>(plane),
                                 slice - static_cast<std::ptrdiff_t>(plane));
    if (same) {
      runs.back().last = k;
      ++repeats;
      longest = std::max(longest, k - runs.back().first + 1);
    } else {
      runs.push_back({k, k});
    }
  }
  // Only a map that repeats many of its slices in short runs was resampled that way; a long run
  // is a part that does not change along the slices (a tube along them), and is kept.
  if (repeats == 0 || 4 * repeats < filled || longest > 4) return;
  // Each run's own distances: those of its first slice (all its slices are alike).
  const std::vector<float> original(field.values.data(), field.values.data() + field.values.size());
  const auto at = [&](const Run& r, std::size_t i) { return original[r.first * plane + i]; };
  for (std::size_t r = 0; r < runs.size(); ++r) {
    if (runs[r].first == runs[r].last) continue;
    for (std::size_t k = runs[r].first; k <= runs[r].last; ++k) {
      const double z = static_cast<double>(k);
      const Run* other = nullptr;
      if (z < runs[r].centre() && r > 0) other = &runs[r - 1];
      if (z > runs[r].centre() && r + 1 < runs.size()) other = &runs[r + 1];
      if (other == nullptr) continue;
      const auto w =
          static_cast<float>((z - runs[r].centre()) / (other->centre() - runs[r].centre()));
      float* out = field.values.data() + k * plane;
      for (std::size_t i = 0; i < plane; ++i)
        out[i] = (1.0F - w) * at(runs[r], i) + w * at(*other, i);
    }
  }
}

/// The slices where a 4-connected region of `mask`'s inside ends (none of its samples is inside
/// in the next slice, or in the one before), with the two slices either side: all that the caps
/// over those ends read (label_caps.h).
std::vector<std::uint8_t> slices_around_ends(const std::vector<std::uint8_t>& mask,
                                             const VolumeGeometry& g) {
  const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  const auto plane = static_cast<std::size_t>(nx * ny);
  std::vector<std::uint8_t> wanted(static_cast<std::size_t>(nz), 0), seen(plane);
  std::vector<std::int64_t> stack;
  for (std::int64_t k = 0; k < nz; ++k) {
    const std::uint8_t* here = mask.data() + static_cast<std::size_t>(k) * plane;
    const std::uint8_t* next = k + 1 < nz ? here + plane : nullptr;
    const std::uint8_t* before = k > 0 ? here - plane : nullptr;
    std::fill(seen.begin(), seen.end(), 0);
    bool ends = false;
    for (std::int64_t seed = 0; seed < nx * ny && !ends; ++seed) {
      if (here[seed] == 0 || seen[static_cast<std::size_t>(seed)] != 0) continue;
      bool goes_on = false, came_from = false;
      stack.assign(1, seed);
      seen[static_cast<std::size_t>(seed)] = 1;
      while (!stack.empty()) {
        const std::int64_t at = stack.back();
        stack.pop_back();
        goes_on = goes_on || (next != nullptr && next[at] != 0);
        came_from = came_from || (before != nullptr && before[at] != 0);
        const std::int64_t x = at % nx, y = at / nx;
        for (const std::int64_t n : {x > 0 ? at - 1 : -1, x + 1 < nx ? at + 1 : -1,
                                     y > 0 ? at - nx : -1, y + 1 < ny ? at + nx : -1}) {
          if (n < 0 || here[n] == 0 || seen[static_cast<std::size_t>(n)] != 0) continue;
          seen[static_cast<std::size_t>(n)] = 1;
          stack.push_back(n);
        }
      }
      ends = !goes_on || !came_from;
    }
    if (!ends) continue;
    for (std::int64_t w = std::max<std::int64_t>(k - 2, 0); w <= std::min(k + 2, nz - 1); ++w)
      wanted[static_cast<std::size_t>(w)] = 1;
  }
  return wanted;
}

// The field marching cubes runs on: shape-based interpolation (Raya and Udupa, "Shape-based
// interpolation of multidimensional objects", 1990). Each slice's samples hold their signed
// in-slice distance to the label's outline (positive inside), so along the slice axis a crossed
// edge is cut where the distance interpolates to zero: between two slices the outline moves
// smoothly instead of in one step per slice, which is what makes terraces. The sign is the
// indicator's (so the crossed edges, and the topology, are those of the 0/1 indicator) except in
// repeated slices, whose distances are interpolated (interpolate_repeated_slices). A slice
// without inside (or outside) samples counts as one slice spacing away. `indicator` gets the
// field's sign: the band the smoothing keeps vertices in.
Grid<float> label_field(const Grid<float>& labels, float label, std::size_t& inside,
                        Grid<float>& indicator) {
  const VolumeGeometry& g = labels.geometry;
  const std::size_t n = labels.values.size();
  std::vector<std::uint8_t> mask(n);
  indicator.geometry = g;
  indicator.values.resize(n);
  std::size_t count = 0;
  for (std::size_t i = 0; i < n; ++i) {
    mask[i] = labels.values[i] == label ? 1 : 0;
    indicator.values[i] = mask[i];
    count += mask[i];
  }
  inside = count;
  Grid<float> field = signed_slice_distances(mask, g, nullptr);
  if (count == 0) return field;
  interpolate_repeated_slices(mask, field);
  for (std::size_t i = 0; i < n; ++i)
    indicator.values[i] = field.values[i] > 0.0F ? 1.0F : 0.0F;
  return field;
}

/// Each vertex's neighbours (CSR): the far ends of its edges.
struct Neighbours {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> adjacency;
  /// Per entry of adjacency, the corner before v in the same face: (v, next, before) spans that
  /// face, so the vertex's normal is their cross products' sum.
  std::vector<std::uint32_t> before;
};

// In a triangle the corner after v names one neighbour; around a closed manifold vertex these
// are all of them, once each. At an open border one is missing, which only weights the average.
Neighbours neighbours_of(const PolygonMesh& mesh) {
  Neighbours nb;
  const std::size_t n = mesh.positions.size();
  nb.offsets.assign(n + 1, 0);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    for (const std::uint32_t v : mesh.face(f))
      ++nb.offsets[v + 1];
  }
  for (std::size_t v = 0; v < n; ++v)
    nb.offsets[v + 1] += nb.offsets[v];
  nb.adjacency.resize(nb.offsets[n]);
  nb.before.resize(nb.offsets[n]);
  std::vector<std::uint32_t> fill(nb.offsets.begin(), nb.offsets.end() - 1);
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    for (std::size_t c = 0; c < face.size(); ++c) {
      nb.before[fill[face[c]]] = face[(c + face.size() - 1) % face.size()];
      nb.adjacency[fill[face[c]]++] = face[(c + 1) % face.size()];
    }
  }
  return nb;
}

Neighbours neighbours_of(const Dlfl& mesh) {
  Neighbours nb;
  const std::size_t n = mesh.vertex_capacity();
  nb.offsets.reserve(n + 1);
  nb.offsets.push_back(0);
  nb.adjacency.reserve(6 * n);
  for (std::uint32_t v = 0; v < n; ++v) {
    const VertexId x(v);
    if (mesh.alive(x)) {
      for (RotationId r = mesh.first_rotation(x); r.valid(); r = mesh.next_rotation(r)) {
        const CornerId start = mesh.rotation_corner(r);
        CornerId c = start;
        do {
          if (!mesh.is_point_sphere(c)) {
            nb.adjacency.push_back(mesh.vertex(mesh.next(c)).idx);
            nb.before.push_back(mesh.vertex(mesh.prev(c)).idx);
          }
          c = mesh.rot_next(c);
        } while (c != start);
      }
    }
    nb.offsets.push_back(static_cast<std::uint32_t>(nb.adjacency.size()));
  }
  return nb;
}

/// The windowed-sinc low-pass filter of Taubin, Zhang and Golub ("Optimal surface smoothing as
/// filter design", 1996) as weights a_i of the Chebyshev terms T_i(1 - k/2), k a frequency of the
/// umbrella Laplacian (0..2): a sinc cut at angle theta + sigma, Hamming-windowed. A filter of
/// low order cannot be as sharp as a small pass band asks, so the cut is moved out by sigma
/// until the gain at the pass band is 1, as the paper does: the shape's own low frequencies then
/// pass unchanged (no shrinkage) and the staircase's high ones do not.
std::vector<double> sinc_weights(std::size_t order, double pass_band) {
  constexpr double kPi = 3.14159265358979323846;
  const double theta = std::acos(1.0 - 0.5 * pass_band);
  std::vector<double> a(order + 1);
  const auto make = [&](double cut) {
    for (std::size_t i = 0; i <= order; ++i) {
      const double d = static_cast<double>(i);
      const double window = 0.54 + 0.46 * std::cos(d * kPi / static_cast<double>(order + 1));
      a[i] = window * (i == 0 ? cut / kPi : 2.0 * std::sin(d * cut) / (d * kPi));
    }
  };
  const auto gain_at_pass_band = [&] {
    double f = 0.0;
    for (std::size_t i = 0; i <= order; ++i)
      f += a[i] * std::cos(static_cast<double>(i) * theta);
    return f;
  };
  // The smallest such sigma: above it the gain at theta ripples about 1 and a larger root would
  // let far more through. Bracketed by steps, then bisected.
  double lo = 0.0, hi = 0.0;
  for (make(theta); gain_at_pass_band() < 1.0 && hi < kPi / 2.0 - theta; make(theta + hi)) {
    lo = hi;
    hi += 0.01;
  }
  for (int it = 0; it < 40; ++it) {
    const double mid = 0.5 * (lo + hi);
    make(theta + mid);
    (gain_at_pass_band() < 1.0 ? lo : hi) = mid;
  }
  make(theta + hi);
  return a;
}

/// Whether a point lies within kBandMargin of a cell (in cells, along each axis) whose corners
/// are neither all inside nor all outside: the band of cells the label's true boundary passes
/// through, where marching cubes put its vertices. The margin lets the filter's surface round
/// the band's corners instead of creasing at them. Outside the grid counts as outside the band.
class BandTest {
 public:
  static constexpr double kBandMargin = 0.25;
  explicit BandTest(const Grid<float>& field) : f_(field) {}
  bool operator()(const Vec3& world) const {
    const Vec3 at = f_.geometry.world_to_index(world);
    if (mixed(at)) return true;
    for (int o = 0; o < 8; ++o)
      if (mixed(at + kBandMargin * Vec3((o & 1) ? 1 : -1, (o & 2) ? 1 : -1, (o & 4) ? 1 : -1)))
        return true;
    return false;
  }

 private:
  [[nodiscard]] bool mixed(const Vec3& ijk) const {
    const auto& d = f_.geometry.dims;
    const Vec3 c = glm::floor(ijk);
    if (c.x < 0 || c.y < 0 || c.z < 0 || c.x >= static_cast<double>(d[0] - 1) ||
        c.y >= static_cast<double>(d[1] - 1) || c.z >= static_cast<double>(d[2] - 1))
      return false;
    const auto i = static_cast<std::int64_t>(c.x), j = static_cast<std::int64_t>(c.y),
               k = static_cast<std::int64_t>(c.z);
    float lo = 1.0F, hi = 0.0F;
    for (int corner = 0; corner < 8; ++corner) {
      const float v = f_.at(i + (corner & 1), j + ((corner >> 1) & 1), k + (corner >> 2));
      lo = std::min(lo, v);
      hi = std::max(hi, v);
    }
    return lo != hi;
  }

  const Grid<float>& f_;
};

/// Each vertex's unit normal: the sum of its faces' area vectors, normalised (0 where they
/// cancel).
void vertex_normals(std::span<const Vec3> pos, const Neighbours& nb, std::vector<Vec3>& normal) {
  for (std::size_t v = 0; v < pos.size(); ++v) {
    Vec3 sum(0.0);
    for (std::uint32_t k = nb.offsets[v]; k < nb.offsets[v + 1]; ++k)
      sum += glm::cross(pos[nb.adjacency[k]] - pos[v], pos[nb.before[k]] - pos[v]);
    const double length = glm::length(sum);
    normal[v] = length > 0.0 ? sum / length : Vec3(0.0);
  }
}

/// Sun, Rosin, Martin and Langbein, "Fast and effective feature-preserving mesh denoising"
/// (2007), section 3.2: each vertex moves along its faces' smooth normals by the mean of its
/// distances to their planes, so each face comes to lie across its smooth normal. The smooth
/// normal of a face is here the mean of its corners' normals (each the sum of its faces' area
/// vectors). `keep(p, v)` is where vertex v may go when it would go to p.
template <class Keep>
void fit_to_smooth_normals(std::span<Vec3> pos, const Neighbours& nb, std::size_t sweeps,
                           Keep&& keep) {
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n), moved(n);
  for (std::size_t sweep = 0; sweep < sweeps; ++sweep) {
    vertex_normals(pos, nb, normal);
    for (std::size_t v = 0; v < n; ++v) {
      const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
      Vec3 move(0.0);
      for (std::uint32_t k = b; k < e; ++k) {
        const std::uint32_t x = nb.adjacency[k], y = nb.before[k];
        const Vec3 smooth = normal[v] + normal[x] + normal[y];
        const double length = glm::length(smooth);
        if (length == 0.0) continue;
        const Vec3 unit = smooth / length;
        move += glm::dot(unit, (pos[x] + pos[y] - 2.0 * pos[v]) / 3.0) * unit;
      }
      moved[v] = b == e ? pos[v] : pos[v] + move / static_cast<double>(e - b);
    }
    for (std::size_t v = 0; v < n; ++v)
      pos[v] = keep(moved[v], v);
  }
}

/// Tangential relaxation, as in isotropic remeshing (Botsch and Kobbelt, "A remeshing approach
/// to multiresolution modeling", 2004): each vertex moves to the centroid of its faces' centres,
/// weighted by their areas, less the part of that move along its normal. The shape stays (to
/// second order in the move) while the thin triangles that the caps and the band leave where a
/// thin part ends in a slice even out, and their normals, mostly their corners' small errors,
/// with them. Where the surface is too coarse for a tangent plane to stand for it (`coarse`,
/// too_coarse_shares) the vertices move less, none where it is wholly so. `keep(p, v)` is where
/// vertex v may go when it would go to p.
template <class Keep>
void relax_along_surface(std::span<Vec3> pos, const Neighbours& nb, std::size_t sweeps,
                         const std::vector<double>& coarse, Keep&& keep) {
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n), moved(n);
  for (std::size_t sweep = 0; sweep < sweeps; ++sweep) {
    vertex_normals(pos, nb, normal);
    for (std::size_t v = 0; v < n; ++v) {
      Vec3 centre(0.0);
      double area = 0.0;
      for (std::uint32_t k = nb.offsets[v]; k < nb.offsets[v + 1]; ++k) {
        const Vec3 x = pos[nb.adjacency[k]], y = pos[nb.before[k]];
        const double a = glm::length(glm::cross(x - pos[v], y - pos[v]));
        centre += a * (pos[v] + x + y) / 3.0;
        area += a;
      }
      const Vec3 move = area > 0.0 ? centre / area - pos[v] : Vec3(0.0);
      moved[v] = pos[v] + (1.0 - coarse[v]) * (move - glm::dot(move, normal[v]) * normal[v]);
    }
    for (std::size_t v = 0; v < n; ++v)
      pos[v] = keep(moved[v], v);
  }
}

/// Each vertex's value averaged with its neighbours', `sweeps` times.
void average_over_neighbours(std::vector<double>& value, const Neighbours& nb, int sweeps) {
  std::vector<double> averaged(value.size());
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    for (std::size_t v = 0; v < value.size(); ++v) {
      const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
      double sum = value[v];
      for (std::uint32_t k = b; k < e; ++k)
        sum += value[nb.adjacency[k]];
      averaged[v] = sum / static_cast<double>(1 + e - b);
    }
    value.swap(averaged);
  }
}

/// How sharply the surface bends at each vertex against its sampling: the largest turn of its
/// normal to a neighbour per millimetre, times its mean edge length, averaged over its
/// neighbourhood.
std::vector<double> bends(std::span<const Vec3> pos, const Neighbours& nb) {
  constexpr int kAveragingSweeps = 5;
  const std::size_t n = pos.size();
  std::vector<Vec3> normal(n);
  vertex_normals(pos, nb, normal);
  std::vector<double> bend(n, 0.0);
  for (std::size_t v = 0; v < n; ++v) {
    const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
    double sharpest = 0.0, edges = 0.0;
    for (std::uint32_t k = b; k < e; ++k) {
      const std::uint32_t x = nb.adjacency[k];
      const double d = glm::length(pos[x] - pos[v]);
      edges += d;
      if (d > 0.0) sharpest = std::max(sharpest, glm::length(normal[x] - normal[v]) / d);
    }
    bend[v] = b == e ? 0.0 : sharpest * edges / static_cast<double>(e - b);
  }
  average_over_neighbours(bend, nb, kAveragingSweeps);
  return bend;
}

/// Each vertex's share of the filtered residual added back (LabelSurfaceOptions::twicing_share),
/// by its bend.
std::vector<double> twicing_shares(const std::vector<double>& bend, const LabelSurfaceOptions& o) {
  const std::size_t n = bend.size();
  std::vector<double> share(n);
  for (std::size_t v = 0; v < n; ++v) {
    const double t = std::clamp(
        (bend[v] - o.twicing_bend_flat) / (o.twicing_bend_sharp - o.twicing_bend_flat), 0.0, 1.0);
    share[v] = o.twicing_share_flat + t * (o.twicing_share - o.twicing_share_flat);
  }
  return share;
}

/// Where the surface turns by about a radian or more from one vertex to the next (a tube two or
/// three samples across: a vessel at 3 mm samples), its samples are too few for a low-pass to
/// tell the shape from the staircase, and the filter draws it in towards its axis (a capsule 3
/// mm in radius at 3 x 3 x 3 mm lay 2.3 mm off RMS, as VTK's does); twicing brings nothing back,
/// since the residual is as sharp. Each vertex's share of too coarse: 1 from a bend of 2, none
/// under 1, averaged over the neighbourhood so the surface does not crease where it changes.
std::vector<double> too_coarse_shares(const std::vector<double>& bend, const Neighbours& nb) {
  constexpr double kFilteredUpTo = 1.0, kKeptFrom = 2.0;
  constexpr int kSpreadSweeps = 3;
  std::vector<double> share(bend.size());
  for (std::size_t v = 0; v < bend.size(); ++v)
    share[v] = std::clamp((bend[v] - kFilteredUpTo) / (kKeptFrom - kFilteredUpTo), 0.0, 1.0);
  average_over_neighbours(share, nb, kSpreadSweeps);
  return share;
}

/// Where too coarse, the vertices go back towards their places from steps 1 and 2 by that share.
template <typename Keep>
void keep_where_too_coarse(std::span<Vec3> pos, std::span<const Vec3> home,
                           const std::vector<double>& coarse, const Keep& kept_in_band) {
  for (std::size_t v = 0; v < coarse.size(); ++v)
    if (coarse[v] > 0.0) pos[v] = kept_in_band(pos[v] + coarse[v] * (home[v] - pos[v]), v);
}

void smooth_in_band(std::span<Vec3> pos, const Neighbours& nb, const Grid<float>& field,
                    const LabelSurfaceOptions& o, LabelSurfaceStats& stats) {
  const auto start = Clock::now();
  const std::size_t n = pos.size();
  const std::vector<Vec3> home(pos.begin(), pos.end());
  const std::vector<double> a = sinc_weights(o.iterations, o.pass_band);
  // x_{i+1} = 2 (I - K/2) x_i - x_{i-1} = x_i + avg(x_i) - x_{i-1}, with x_1 = (x_0 + avg(x_0))/2.
  std::vector<Vec3> prev(n), cur(n), next(n);
  const auto average = [&](const std::vector<Vec3>& x, std::size_t v) {
    const std::uint32_t b = nb.offsets[v], e = nb.offsets[v + 1];
    if (b == e) return x[v];
    Vec3 sum(0.0);
    for (std::uint32_t k = b; k < e; ++k)
      sum += x[nb.adjacency[k]];
    return sum / static_cast<double>(e - b);
  };
  const BandTest in_band(field);
  std::size_t clamped = 0;
  std::vector<Vec3> input(n);
  // out = F(input), F the filter: sum of a_i x_i.
  const auto filter = [&](std::vector<Vec3>& out) {
    std::copy(input.begin(), input.end(), prev.begin());
    for (std::size_t v = 0; v < n; ++v) {
      cur[v] = 0.5 * (prev[v] + average(prev, v));
      out[v] = a[0] * prev[v] + a[1] * cur[v];
    }
    for (std::size_t i = 2; i <= o.iterations; ++i) {
      for (std::size_t v = 0; v < n; ++v) {
        next[v] = cur[v] + average(cur, v) - prev[v];
        out[v] += a[i] * next[v];
      }
      std::swap(prev, cur);
      std::swap(cur, next);
    }
  };
  std::vector<Vec3> smoothed(n), back(n);
  std::vector<double> bend, share;  // per vertex, set after the first round
  std::vector<std::uint8_t> held(n, 0);
  constexpr int kSpreadSweeps = 4;
  // From `from` (in the band) towards `to`: as far as the band goes.
  const auto towards_in_band = [&](const Vec3& from, const Vec3& to) {
    double lo = 0.0, hi = 1.0;
    for (int it = 0; it < 12; ++it) {
      const double mid = 0.5 * (lo + hi);
      (in_band(from + mid * (to - from)) ? lo : hi) = mid;
    }
    return from + lo * (to - from);
  };
  // Where vertex v may go when it would go to p: there if in the band, else as far towards it
  // from its marching-cubes position as the band goes.
  const auto kept_in_band = [&](const Vec3& p, std::size_t v) {
    return in_band(p) ? p : towards_in_band(home[v], p);
  };
  for (std::size_t round = 0; round < o.rounds; ++round) {
    // Round 0 filters the positions; each later one filters what is left between them and the
    // marching-cubes ones and adds a share w of it back (Tukey's twicing, gain (1 + w)F - wF^2
    // after two), which flattens the pass band, so curved parts shrink less while the staircase
    // stays filtered.
    for (std::size_t v = 0; v < n; ++v)
      input[v] = round == 0 ? Vec3(home[v]) : home[v] - pos[v];
    filter(smoothed);
    if (round == 0) {
      std::copy(smoothed.begin(), smoothed.end(), pos.begin());
    } else {
      if (share.empty()) {
        bend = bends(pos, nb);
        share = twicing_shares(bend, o);
      }
      for (std::size_t v = 0; v < n; ++v)
        pos[v] += share[v] * smoothed[v];
    }
    // Back into the band the voxels allow: along the way from its marching-cubes position (a
    // point of the band), as far as the band goes.
    clamped = 0;
    std::fill(held.begin(), held.end(), 0);
    for (std::size_t v = 0; v < n; ++v) {
      back[v] = Vec3(0.0);
      if (in_band(pos[v])) continue;
      ++clamped;
      held[v] = 1;
      back[v] = towards_in_band(home[v], pos[v]) - pos[v];
    }
    // The held vertices' way back spreads to their neighbours, fading (each free vertex takes
    // its neighbours' mean a few times): the surface bends back into the band instead of
    // creasing round each held vertex.
    if (clamped > 0) {
      std::vector<Vec3> spread(back);
      for (int sweep = 0; sweep < kSpreadSweeps; ++sweep) {
        for (std::size_t v = 0; v < n; ++v)
          if (!held[v]) spread[v] = average(back, v);
        back.swap(spread);
      }
      for (std::size_t v = 0; v < n; ++v)
        pos[v] = kept_in_band(pos[v] + back[v], v);
    }
    if (o.smooth_progress) o.smooth_progress(round + 1, o.rounds);
  }
  std::vector<double> coarse(n, 0.0);
  if (!bend.empty()) {
    coarse = too_coarse_shares(bend, nb);
    keep_where_too_coarse(pos, home, coarse, kept_in_band);
  }
  relax_along_surface(pos, nb, o.tangential_sweeps, coarse, kept_in_band);
  fit_to_smooth_normals(pos, nb, o.normal_fit_sweeps, kept_in_band);
  stats.clamped_last = clamped;
  stats.smooth_seconds = seconds_since(start);
}

IsoSurfaceOptions iso_options(const LabelSurfaceOptions& o) {
  IsoSurfaceOptions iso;
  iso.iso = 0.0F;
  iso.placement = VertexPlacement::Linear;
  iso.progress = o.progress;
  iso.build_progress = o.build_progress;
  return iso;
}

}  // namespace

Grid<float> downsample_label(const Grid<float>& labels, float label,
                             const std::array<int, 3>& factors) {
  if (factors[0] < 1 || factors[1] < 1 || factors[2] < 1 || label == 0.0F) {
    throw InputError("downsample_label: factors must be at least 1 and the label not 0");
  }
  const VolumeGeometry& g = labels.geometry;
  Grid<float> out;
  VolumeGeometry& c = out.geometry;
  c.direction = g.direction;
  glm::dvec3 shift(0.0);
  for (int a = 0; a < 3; ++a) {
    c.dims[a] = (g.dims[a] + factors[a] - 1) / factors[a] + 2;  // and a background border
    c.spacing[a] = g.spacing[a] * factors[a];
    shift[a] = 0.5 * g.spacing[a] * (factors[a] - 1) - c.spacing[a];
  }
  c.origin = g.origin + g.direction * shift;
  out.values.resize(c.voxel_count());
  std::vector<std::uint32_t> inside(c.voxel_count(), 0), total(c.voxel_count(), 0);
  for (std::int64_t k = 0; k < g.dims[2]; ++k) {
    for (std::int64_t j = 0; j < g.dims[1]; ++j) {
      const float* row = labels.values.data() + g.linear_index(0, j, k);
      const std::size_t base = c.linear_index(1, 1 + j / factors[1], 1 + k / factors[2]);
      for (std::int64_t i = 0; i < g.dims[0]; ++i) {
        const std::size_t b = base + static_cast<std::size_t>(i / factors[0]);
        inside[b] += row[i] == label ? 1U : 0U;
        ++total[b];
      }
    }
  }
  for (std::size_t b = 0; b < inside.size(); ++b)
    out.values[b] = inside[b] > 0 && 2 * inside[b] >= total[b] ? label : 0.0F;
  return out;
}

std::size_t label_voxel_count(const Grid<float>& labels, float label) {
  return static_cast<std::size_t>(
      std::count(labels.values.data(), labels.values.data() + labels.values.size(), label));
}

namespace {

/// The label's smooth indicator field and the band of cells its boundary crosses (both
/// extractions start here).
struct LabelIndicator {
  Grid<float> field;
  Grid<float> band;
  /// The map read with its thickest axis as k (slices_across_k), where that is not k already;
  /// empty where it is.
  Grid<float> turned;
  [[nodiscard]] const Grid<float>& sliced(const Grid<float>& labels) const {
    return turned.values.empty() ? labels : turned;
  }
};

/// Samples further apart along one axis than along another by this factor or more are thicker.
constexpr double kThicker = 1.2;

/// `labels` read with index axis `axis` and k swapped (every sample keeps its world position):
/// its geometry into `turned`, and each sample as `value` makes it into `out`.
template <typename T, typename Value>
void swap_with_k(const Grid<float>& labels, int axis, VolumeGeometry& turned, T* out,
                 const Value& value) {
  const VolumeGeometry& g = labels.geometry;
  std::array<int, 3> from{0, 1, 2};  // the axis of `labels` each axis of `turned` is
  std::swap(from[static_cast<std::size_t>(axis)], from[2]);
  VolumeGeometry& t = turned;
  t.origin = g.origin;
  for (int a = 0; a < 3; ++a) {
    const int f = from[static_cast<std::size_t>(a)];
    t.dims[static_cast<std::size_t>(a)] = g.dims[static_cast<std::size_t>(f)];
    t.spacing[a] = g.spacing[f];
    t.direction[a] = g.direction[f];
  }
  std::array<std::int64_t, 3> at{};  // the sample of `labels` for (i, j, k) of `turned`
  for (std::int64_t k = 0; k < t.dims[2]; ++k)
    for (std::int64_t j = 0; j < t.dims[1]; ++j)
      for (std::int64_t i = 0; i < t.dims[0]; ++i) {
        at[static_cast<std::size_t>(from[0])] = i;
        at[static_cast<std::size_t>(from[1])] = j;
        at[static_cast<std::size_t>(from[2])] = k;
        out[t.linear_index(i, j, k)] = value(labels.values[g.linear_index(at[0], at[1], at[2])]);
      }
}

/// The steps above take the slices across k: shape-based interpolation runs between them and
/// the caps go over the last ones. A map whose samples are furthest apart along i or j (a
/// sagittal or coronal series), by a fifth more than along k, is read with that axis and k
/// swapped: its index axes and their spacings and world directions trade places, so every
/// sample keeps its world position (and marching cubes' winding follows the direction's
/// handedness). Nearly isotropic maps stay as they are (their repeated slices, if any, lie
/// across k). `turned` holds the copy; the map itself is returned when it is not turned.
const Grid<float>& slices_across_k(const Grid<float>& labels, Grid<float>& turned) {
  const VolumeGeometry& g = labels.geometry;
  int thick = 2;
  for (int a = 0; a < 2; ++a)
    if (g.spacing[a] > kThicker * g.spacing[2] && g.spacing[a] > g.spacing[thick]) thick = a;
  if (thick == 2) return labels;
  turned.values.resize(labels.values.size());
  swap_with_k(labels, thick, turned.geometry, turned.values.data(), [](float v) { return v; });
  return turned;
}

/// At about even sampling a shape's tips along i and j (not only its ends across the slices) are
/// the ends of regions of slices across those axes, and bulge past the midpoints marching cubes
/// puts their vertices at: smoothed, an ellipsoid at 1.3 mm samples lay 0.47 mm inside at the
/// tips of its long axis (VTK's surface 0.43), and lies 0.37 mm off with their caps. Slices
/// across an axis whose samples lie about as far apart as the slices' (within a fifth) give
/// those tips their caps, where the caps lie further out.
void place_ends_across_other_axes(std::span<Vec3> positions, const Grid<float>& sliced,
                                  float label) {
  for (int a = 0; a < 2; ++a) {
    if (kThicker * sliced.geometry.spacing[a] < sliced.geometry.spacing[2]) continue;
    VolumeGeometry across;
    std::vector<std::uint8_t> mask(sliced.values.size());
    swap_with_k(sliced, a, across, mask.data(),
                [label](float v) -> std::uint8_t { return v == label ? 1 : 0; });
    const std::vector<std::uint8_t> wanted = slices_around_ends(mask, across);
    place_vertices_across_slices(positions, signed_slice_distances(mask, across, &wanted),
                                 AcrossSlices::EndsFurtherOut);
  }
}

LabelIndicator label_indicator(const Grid<float>& labels, float label,
                               const LabelSurfaceOptions& options, LabelSurfaceStats& s) {
  check_options(options);
  const auto t = Clock::now();
  LabelIndicator out;
  out.field = label_field(slices_across_k(labels, out.turned), label, s.label_voxels, out.band);
  s.indicator_seconds = seconds_since(t);
  return out;
}

}  // namespace

PolygonMesh extract_label_surface_mesh(const Grid<float>& labels, float label,
                                       const LabelSurfaceOptions& options,
                                       LabelSurfaceStats* stats) {
  LabelSurfaceStats local;
  LabelSurfaceStats& s = stats ? *stats : local;
  const LabelIndicator in = label_indicator(labels, label, options, s);
  const Grid<float>& band = in.band;
  PolygonMesh mesh = extract_isosurface_mesh(in.field, iso_options(options), &s.extraction);
  place_vertices_across_slices({mesh.positions.data(), mesh.positions.size()}, in.field);
  place_ends_across_other_axes({mesh.positions.data(), mesh.positions.size()}, in.sliced(labels),
                               label);
  if (options.iterations > 0 && options.rounds > 0 && !mesh.positions.empty()) {
    smooth_in_band({mesh.positions.data(), mesh.positions.size()}, neighbours_of(mesh), band,
                   options, s);
  }
  return mesh;
}

Dlfl extract_label_surface(const Grid<float>& labels, float label,
                           const LabelSurfaceOptions& options, LabelSurfaceStats* stats) {
  LabelSurfaceStats local;
  LabelSurfaceStats& s = stats ? *stats : local;
  const LabelIndicator in = label_indicator(labels, label, options, s);
  const Grid<float>& band = in.band;
  Dlfl mesh = extract_isosurface(in.field, iso_options(options), &s.extraction);
  place_vertices_across_slices({mesh.positions().data(), mesh.vertex_capacity()}, in.field);
  place_ends_across_other_axes({mesh.positions().data(), mesh.vertex_capacity()}, in.sliced(labels),
                               label);
  if (options.iterations > 0 && options.rounds > 0 && mesh.vertex_capacity() > 0) {
    auto& pos = mesh.positions();
    smooth_in_band({pos.data(), mesh.vertex_capacity()}, neighbours_of(mesh), band, options, s);
  }
  return mesh;
}

}  // namespace bisturi
