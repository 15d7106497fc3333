// 3-D split-and-merge (Horowitz-Pavlidis) over the BONO subdivision of the volume.

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/bono_octree.h"
#include "bisturi/scene/volume/segmentation.h"
#include "checks.h"

namespace bisturi {

namespace {

struct Region {
  BonoBox box;
  float min;
  float max;
};

class Splitter {
 public:
  Splitter(const Volume& volume, float tolerance) : volume_(volume), tolerance_(tolerance) {}

  // Post-order: a node whose whole range is homogeneous replaces its children's regions.
  std::pair<float, float> process(const BonoBox& box, int bits) {
    if (box.size[0] == 1 && box.size[1] == 1 && box.size[2] == 1) {
      const float v = volume_.at(box.origin[0], box.origin[1], box.origin[2]);
      regions_.push_back({box, v, v});
      return {v, v};
    }
    const std::size_t start = regions_.size();
    const BonoSplit s = BonoOctree::split(box, bits);
    float mn = std::numeric_limits<float>::infinity();
    float mx = -std::numeric_limits<float>::infinity();
    for (int c = 0; c < s.count; ++c) {
      const auto [cmn, cmx] = process(s.boxes[static_cast<std::size_t>(c)], s.child_bits);
      mn = std::min(mn, cmn);
      mx = std::max(mx, cmx);
    }
    if (mx - mn <= tolerance_) {
      regions_.resize(start);
      regions_.push_back({box, mn, mx});
    }
    return {mn, mx};
  }

  std::vector<Region>& regions() { return regions_; }

 private:
  const Volume& volume_;
  float tolerance_;
  std::vector<Region> regions_;
};

struct RegionSets {
  std::vector<std::uint32_t> parent;
  std::vector<float> min;
  std::vector<float> max;
  std::vector<double> sum;
  std::vector<std::int64_t> count;

  std::uint32_t find(std::uint32_t x) {
    std::uint32_t root = x;
    while (parent[root] != root)
      root = parent[root];
    while (parent[x] != root) {
      const std::uint32_t next = parent[x];
      parent[x] = root;
      x = next;
    }
    return root;
  }
  // Joins two roots; the smaller index stays the root.
  void join(std::uint32_t a, std::uint32_t b) {
    if (b < a) std::swap(a, b);
    parent[b] = a;
    min[a] = std::min(min[a], min[b]);
    max[a] = std::max(max[a], max[b]);
    sum[a] += sum[b];
    count[a] += count[b];
  }
  double mean(std::uint32_t r) const { return sum[r] / static_cast<double>(count[r]); }
};

// Calls fn(index_a, index_b) for every face-adjacent voxel pair, in memory order of the first.
template <class Fn>
void for_each_face_pair(const std::array<std::int64_t, 3>& dims, Fn&& fn) {
  const std::int64_t nx = dims[0];
  const std::int64_t sy = nx;
  const std::int64_t sz = nx * dims[1];
  std::int64_t index = 0;
  for (std::int64_t k = 0; k < dims[2]; ++k) {
    for (std::int64_t j = 0; j < dims[1]; ++j) {
      for (std::int64_t i = 0; i < nx; ++i, ++index) {
        if (i + 1 < nx) fn(index, index + 1);
        if (j + 1 < dims[1]) fn(index, index + sy);
        if (k + 1 < dims[2]) fn(index, index + sz);
      }
    }
  }
}

}  // namespace

LabelVolume split_and_merge(const Volume& volume, const SplitMergeOptions& options) {
  segmentation_detail::check_grid(volume, "split and merge");
  if (!(options.tolerance >= 0)) {
    throw InputError("split and merge: tolerance " + std::to_string(options.tolerance) +
                     " must be a number >= 0");
  }
  const auto& dims = volume.geometry.dims;

  // 1. Split.
  Splitter splitter(volume, options.tolerance);
  BonoBox whole;
  whole.size = dims;
  splitter.process(whole, BonoOctree::root_bits(dims));
  std::vector<Region>& regions = splitter.regions();
  if (regions.size() >= std::numeric_limits<std::uint32_t>::max()) {
    throw InputError("split and merge: more than 2^32 regions; raise the tolerance");
  }
  const auto region_count = static_cast<std::uint32_t>(regions.size());

  LabelVolume out;
  out.geometry = volume.geometry;
  out.values.resize(volume.values.size());
  std::uint32_t* ids = out.values.data();
  RegionSets sets;
  sets.parent.resize(region_count);
  sets.min.resize(region_count);
  sets.max.resize(region_count);
  sets.sum.assign(region_count, 0.0);
  sets.count.resize(region_count);
  for (std::uint32_t r = 0; r < region_count; ++r) {
    const Region& region = regions[r];
    sets.parent[r] = r;
    sets.min[r] = region.min;
    sets.max[r] = region.max;
    sets.count[r] = region.box.sample_count();
    const auto& o = region.box.origin;
    const auto& s = region.box.size;
    double sum = 0;
    for (std::int64_t k = o[2]; k < o[2] + s[2]; ++k) {
      for (std::int64_t j = o[1]; j < o[1] + s[1]; ++j) {
        const std::size_t base = volume.geometry.linear_index(o[0], j, k);
        for (std::int64_t i = 0; i < s[0]; ++i) {
          ids[base + static_cast<std::size_t>(i)] = r;
          sum += static_cast<double>(volume.values[base + static_cast<std::size_t>(i)]);
        }
      }
    }
    sets.sum[r] = sum;
  }
  std::vector<Region>().swap(regions);

  // 2. Merge face-adjacent regions while the union stays homogeneous.
  for_each_face_pair(dims, [&](std::int64_t a, std::int64_t b) {
    const std::uint32_t ia = ids[a];
    const std::uint32_t ib = ids[b];
    if (ia == ib) return;
    const std::uint32_t ra = sets.find(ia);
    const std::uint32_t rb = sets.find(ib);
    if (ra == rb) return;
    if (std::max(sets.max[ra], sets.max[rb]) - std::min(sets.min[ra], sets.min[rb]) <=
        options.tolerance) {
      sets.join(ra, rb);
    }
  });

  // 3. Small regions join the face-adjacent region of closest mean, until none can.
  if (options.min_region_voxels > 1) {
    constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
    std::vector<std::uint32_t> best(region_count, kNone);
    std::vector<double> best_gap(region_count, 0.0);
    for (bool changed = true; changed;) {
      changed = false;
      std::fill(best.begin(), best.end(), kNone);
      auto consider = [&](std::uint32_t small, std::uint32_t other) {
        if (sets.count[small] >= options.min_region_voxels) return;
        const double gap = std::abs(sets.mean(small) - sets.mean(other));
        if (best[small] == kNone || gap < best_gap[small] ||
            (gap == best_gap[small] && other < best[small])) {
          best[small] = other;
          best_gap[small] = gap;
        }
      };
      for_each_face_pair(dims, [&](std::int64_t a, std::int64_t b) {
        const std::uint32_t ia = ids[a];
        const std::uint32_t ib = ids[b];
        if (ia == ib) return;
        const std::uint32_t ra = sets.find(ia);
        const std::uint32_t rb = sets.find(ib);
        if (ra == rb) return;
        consider(ra, rb);
        consider(rb, ra);
      });
      for (std::uint32_t r = 0; r < region_count; ++r) {
        if (best[r] == kNone) continue;
        const std::uint32_t ra = sets.find(r);
        const std::uint32_t rb = sets.find(best[r]);
        if (ra == rb) continue;
        sets.join(ra, rb);
        changed = true;
      }
    }
  }

  // 4. Labels in order of each region's first voxel.
  std::vector<std::uint32_t> label_of(region_count, 0);
  std::uint32_t next = 0;
  for (std::size_t index = 0; index < out.values.size(); ++index) {
    const std::uint32_t root = sets.find(ids[index]);
    if (label_of[root] == 0) label_of[root] = ++next;
    ids[index] = label_of[root];
  }
  out.label_count = next;
  return out;
}

}  // namespace bisturi
