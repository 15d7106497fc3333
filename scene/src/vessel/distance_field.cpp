#include "bisturi/scene/vessel/distance_field.h"

#include <cmath>
#include <limits>
#include <vector>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// One 1-D pass: out[p] = min_q (f[q] + (h (p - q))^2) over the finite f[q].
/// v, z: scratch (the envelope's parabola sites and boundaries).
void envelope_pass(const std::vector<double>& f, double h, std::vector<double>& out,
                   std::vector<std::int64_t>& v, std::vector<double>& z) {
  const auto n = static_cast<std::int64_t>(f.size());
  const double h2 = h * h;
  v.clear();
  z.clear();
  for (std::int64_t q = 0; q < n; ++q) {
    if (!std::isfinite(f[static_cast<std::size_t>(q)])) continue;
    const double fq = f[static_cast<std::size_t>(q)] + h2 * static_cast<double>(q * q);
    while (!v.empty()) {
      const std::int64_t r = v.back();
      const double fr = f[static_cast<std::size_t>(r)] + h2 * static_cast<double>(r * r);
      const double s = (fq - fr) / (2.0 * h2 * static_cast<double>(q - r));
      if (s <= z.back()) {
        v.pop_back();
        z.pop_back();
      } else {
        v.push_back(q);
        z.push_back(s);
        break;
      }
    }
    if (v.empty()) {
      v.push_back(q);
      z.push_back(-kInf);
    }
  }
  if (v.empty()) {
    for (std::int64_t p = 0; p < n; ++p)
      out[static_cast<std::size_t>(p)] = kInf;
    return;
  }
  std::size_t k = 0;
  for (std::int64_t p = 0; p < n; ++p) {
    while (k + 1 < v.size() && z[k + 1] < static_cast<double>(p))
      ++k;
    const double d = h * static_cast<double>(p - v[k]);
    out[static_cast<std::size_t>(p)] = f[static_cast<std::size_t>(v[k])] + d * d;
  }
}

}  // namespace

Grid<float> distance_to_outside(const Grid<std::uint8_t>& mask) {
  const VolumeGeometry& g = mask.geometry;
  if (mask.values.size() != g.voxel_count() || g.voxel_count() == 0) {
    throw InputError("distance field: the mask's values do not match its dims");
  }
  const std::int64_t n[3] = {g.dims[0], g.dims[1], g.dims[2]};
  const double h[3] = {g.spacing.x, g.spacing.y, g.spacing.z};
  std::vector<double> squared(g.voxel_count());
  for (std::size_t i = 0; i < squared.size(); ++i)
    squared[i] = mask.values[i] != 0 ? kInf : 0.0;

  std::vector<double> line, out;
  std::vector<std::int64_t> v;
  std::vector<double> z;
  const std::int64_t stride[3] = {1, n[0], n[0] * n[1]};
  for (int axis = 0; axis < 3; ++axis) {
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    line.resize(static_cast<std::size_t>(n[axis]));
    out.resize(line.size());
    for (std::int64_t jb = 0; jb < n[b]; ++jb) {
      for (std::int64_t ja = 0; ja < n[a]; ++ja) {
        const std::int64_t base = ja * stride[a] + jb * stride[b];
        for (std::int64_t p = 0; p < n[axis]; ++p)
          line[static_cast<std::size_t>(p)] =
              squared[static_cast<std::size_t>(base + p * stride[axis])];
        envelope_pass(line, h[axis], out, v, z);
        for (std::int64_t p = 0; p < n[axis]; ++p)
          squared[static_cast<std::size_t>(base + p * stride[axis])] =
              out[static_cast<std::size_t>(p)];
      }
    }
  }
  Grid<float> field;
  field.geometry = g;
  field.values.resize(squared.size());
  for (std::size_t i = 0; i < squared.size(); ++i)
    field.values[i] = static_cast<float>(std::sqrt(squared[i]));
  return field;
}

}  // namespace bisturi
