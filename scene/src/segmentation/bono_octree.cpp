// BONO construction (seed section 2.2.1.1): structure breadth-first, then min/max bottom-up.

#include "bisturi/scene/volume/bono_octree.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <limits>
#include <string>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

void check_dims(const std::array<std::int64_t, 3>& dims, const BonoOptions& options) {
  for (int a = 0; a < 3; ++a) {
    if (dims[a] < 1) {
      throw InputError("BONO octree: volume dimensions " + std::to_string(dims[0]) + "x" +
                       std::to_string(dims[1]) + "x" + std::to_string(dims[2]) +
                       " must be at least 1 along every axis");
    }
  }
  if (options.leaf_size < 1) {
    throw InputError("BONO octree: leaf_size " + std::to_string(options.leaf_size) +
                     " must be at least 1");
  }
}

// Min/max of the samples in [lo, hi) of a grid, hi already clamped to the dims.
template <class T>
void scan_range(const Grid<T>& volume, const std::array<std::int64_t, 3>& lo,
                const std::array<std::int64_t, 3>& hi, float& mn, float& mx) {
  const auto& dims = volume.geometry.dims;
  const T* data = volume.values.data();
  float lo_v = std::numeric_limits<float>::infinity();
  float hi_v = -std::numeric_limits<float>::infinity();
  for (std::int64_t k = lo[2]; k < hi[2]; ++k) {
    for (std::int64_t j = lo[1]; j < hi[1]; ++j) {
      const T* row = data + (lo[0] + dims[0] * (j + dims[1] * k));
      const std::int64_t n = hi[0] - lo[0];
      for (std::int64_t i = 0; i < n; ++i) {
        const auto v = static_cast<float>(row[i]);
        lo_v = v < lo_v ? v : lo_v;  // NaN never wins
        hi_v = v > hi_v ? v : hi_v;
      }
    }
  }
  mn = lo_v;
  mx = hi_v;
}

}  // namespace

int BonoOctree::root_bits(const std::array<std::int64_t, 3>& dims) {
  std::uint64_t largest = 0;
  for (int a = 0; a < 3; ++a) {
    if (dims[a] > 1) largest = std::max(largest, static_cast<std::uint64_t>(dims[a] - 1));
  }
  return static_cast<int>(std::bit_width(largest));
}

BonoSplit BonoOctree::split(const BonoBox& box, int bits) {
  BonoSplit out;
  for (int w = bits; w >= 1; --w) {
    const std::int64_t half = std::int64_t{1} << (w - 1);
    std::array<bool, 3> splits{};
    bool any = false;
    for (int a = 0; a < 3; ++a) {
      splits[a] = box.size[a] >= 1 && ((box.size[a] - 1) & half) != 0;
      any = any || splits[a];
    }
    if (!any) continue;
    out.child_bits = w - 1;
    for (unsigned code = 0; code < 8; ++code) {
      BonoBox child;
      bool valid = true;
      for (int a = 0; a < 3; ++a) {
        const bool high = ((code >> a) & 1U) != 0;
        if (high && !splits[a]) {
          valid = false;
          break;
        }
        if (!splits[a]) {
          child.origin[a] = box.origin[a];
          child.size[a] = box.size[a];
        } else if (!high) {
          child.origin[a] = box.origin[a];
          child.size[a] = half;
        } else {
          child.origin[a] = box.origin[a] + half;
          child.size[a] = box.size[a] - half;
        }
      }
      if (!valid) continue;
      out.boxes[static_cast<std::size_t>(out.count)] = child;
      out.codes[static_cast<std::size_t>(out.count)] = static_cast<std::uint8_t>(code);
      ++out.count;
    }
    return out;
  }
  return out;
}

void BonoOctree::build_structure(const std::array<std::int64_t, 3>& dims, const Options& options) {
  check_dims(dims, options);
  dims_ = dims;
  nodes_.clear();
  leaf_count_ = 0;
  Node root;
  root.box.size = dims;
  root.bits = static_cast<std::uint8_t>(root_bits(dims));
  nodes_.push_back(root);
  for (std::size_t index = 0; index < nodes_.size(); ++index) {
    const BonoBox box = nodes_[index].box;
    if (box.size[0] <= options.leaf_size && box.size[1] <= options.leaf_size &&
        box.size[2] <= options.leaf_size) {
      ++leaf_count_;
      continue;
    }
    const BonoSplit s = split(box, nodes_[index].bits);
    if (s.count == 0) {  // a single sample (cannot happen with leaf_size >= 1)
      ++leaf_count_;
      continue;
    }
    if (nodes_.size() + static_cast<std::size_t>(s.count) >
        std::numeric_limits<std::uint32_t>::max()) {
      throw InputError("BONO octree: more than 2^32 nodes; use a larger leaf_size");
    }
    nodes_[index].first_child = static_cast<std::uint32_t>(nodes_.size());
    nodes_[index].child_count = static_cast<std::uint8_t>(s.count);
    for (int c = 0; c < s.count; ++c) {
      Node child;
      child.box = s.boxes[static_cast<std::size_t>(c)];
      child.code = s.codes[static_cast<std::size_t>(c)];
      child.bits = static_cast<std::uint8_t>(s.child_bits);
      nodes_.push_back(child);
    }
  }
}

BonoOctree BonoOctree::build_geometry(const std::array<std::int64_t, 3>& dims,
                                      const Options& options) {
  BonoOctree tree;
  tree.build_structure(dims, options);
  return tree;
}

template <class T>
BonoOctree BonoOctree::build(const Grid<T>& volume, const Options& options) {
  const auto& dims = volume.geometry.dims;
  check_dims(dims, options);
  if (volume.values.size() != volume.geometry.voxel_count()) {
    throw InputError("BONO octree: the volume has " + std::to_string(volume.values.size()) +
                     " values for " + std::to_string(volume.geometry.voxel_count()) + " samples");
  }
  BonoOctree tree;
  tree.build_structure(dims, options);
  // Leaves scan the samples their cells touch; parents take the range of their children (whose
  // extended boxes cover exactly the parent's extended box). Children follow their parent.
  for (std::size_t index = tree.nodes_.size(); index-- > 0;) {
    Node& n = tree.nodes_[index];
    if (n.child_count == 0) {
      std::array<std::int64_t, 3> hi{};
      for (int a = 0; a < 3; ++a)
        hi[a] = std::min(n.box.origin[a] + n.box.size[a] + 1, dims[a]);
      scan_range(volume, n.box.origin, hi, n.min, n.max);
    } else {
      float mn = std::numeric_limits<float>::infinity();
      float mx = -std::numeric_limits<float>::infinity();
      for (std::uint32_t c = 0; c < n.child_count; ++c) {
        const Node& child = tree.nodes_[n.first_child + c];
        mn = std::min(mn, child.min);
        mx = std::max(mx, child.max);
      }
      n.min = mn;
      n.max = mx;
    }
  }
  return tree;
}

template BonoOctree BonoOctree::build(const Grid<float>&, const Options&);
template BonoOctree BonoOctree::build(const Grid<double>&, const Options&);
template BonoOctree BonoOctree::build(const Grid<std::uint8_t>&, const Options&);
template BonoOctree BonoOctree::build(const Grid<std::int16_t>&, const Options&);
template BonoOctree BonoOctree::build(const Grid<std::uint16_t>&, const Options&);
template BonoOctree BonoOctree::build(const Grid<std::uint32_t>&, const Options&);

}  // namespace bisturi
