// Region growing from one seed voxel (flood fill over the voxels inside [lo, hi]).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/segmentation.h"
#include "checks.h"

namespace bisturi {

Grid<std::uint8_t> region_grow(const Volume& volume, std::array<std::int64_t, 3> seed, float lo,
                               float hi, Connectivity connectivity) {
  segmentation_detail::check_grid(volume, "region growing");
  const auto& g = volume.geometry;
  const std::string seed_text = "seed (" + std::to_string(seed[0]) + ", " +
                                std::to_string(seed[1]) + ", " + std::to_string(seed[2]) + ")";
  if (std::isnan(lo) || std::isnan(hi) || lo > hi) {
    throw InputError("region growing from " + seed_text + ": range [" + std::to_string(lo) + ", " +
                     std::to_string(hi) + "] is empty or not a number");
  }
  if (!g.contains(seed[0], seed[1], seed[2])) {
    throw InputError("region growing: " + seed_text + " is outside the volume of " +
                     std::to_string(g.dims[0]) + "x" + std::to_string(g.dims[1]) + "x" +
                     std::to_string(g.dims[2]) + " samples");
  }
  const float seed_value = volume.at(seed[0], seed[1], seed[2]);
  if (!(seed_value >= lo && seed_value <= hi)) {
    throw InputError("region growing: " + seed_text + " has value " + std::to_string(seed_value) +
                     ", outside [" + std::to_string(lo) + ", " + std::to_string(hi) + "]");
  }

  Grid<std::uint8_t> mask;
  mask.geometry = g;
  mask.values.assign(volume.values.size(), 0);
  std::uint8_t* m = mask.values.data();
  const float* v = volume.values.data();
  const std::int64_t nx = g.dims[0];
  const std::int64_t ny = g.dims[1];
  const std::int64_t nz = g.dims[2];
  const std::int64_t sx = 1;
  const std::int64_t sy = nx;
  const std::int64_t sz = nx * ny;
  const bool full = connectivity == Connectivity::TwentySix;

  std::vector<std::int64_t> stack;
  const std::int64_t start = static_cast<std::int64_t>(g.linear_index(seed[0], seed[1], seed[2]));
  m[start] = 1;
  stack.push_back(start);
  auto visit = [&](std::int64_t index) {
    if (m[index] != 0) return;
    const float x = v[index];
    if (x >= lo && x <= hi) {
      m[index] = 1;
      stack.push_back(index);
    }
  };
  while (!stack.empty()) {
    const std::int64_t index = stack.back();
    stack.pop_back();
    const std::int64_t i = index % nx;
    const std::int64_t j = (index / nx) % ny;
    const std::int64_t k = index / sz;
    if (!full) {
      if (i > 0) visit(index - sx);
      if (i + 1 < nx) visit(index + sx);
      if (j > 0) visit(index - sy);
      if (j + 1 < ny) visit(index + sy);
      if (k > 0) visit(index - sz);
      if (k + 1 < nz) visit(index + sz);
      continue;
    }
    for (std::int64_t dk = -1; dk <= 1; ++dk) {
      if (k + dk < 0 || k + dk >= nz) continue;
      for (std::int64_t dj = -1; dj <= 1; ++dj) {
        if (j + dj < 0 || j + dj >= ny) continue;
        for (std::int64_t di = -1; di <= 1; ++di) {
          if (i + di < 0 || i + di >= nx) continue;
          visit(index + di * sx + dj * sy + dk * sz);
        }
      }
    }
  }
  return mask;
}

}  // namespace bisturi
