// Step 1 of label surfaces: shape-based interpolation between slices (see label_field.h).

#include "label_field.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <span>
#include <vector>

namespace bisturi {

namespace {

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

}  // namespace

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

namespace {

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

}  // namespace

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

}  // namespace bisturi
