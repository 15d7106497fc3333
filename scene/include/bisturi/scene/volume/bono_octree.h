#pragma once
// BONO, the branch-on-need octree of Wilhelms and Van Gelder (seed section 2.2.1.1, tables 4-5),
// over the samples of a volume whose sides need not be powers of two.
//
// Every node has a bit width w (the root's is the bit length of its largest extent, where an
// axis' extent is its sample count minus one). At width w an axis splits only if bit w-1 of its
// extent is 1: the low child (code bit 0) gets the largest power of two, 2^(w-1) samples (extent
// a string of w-1 ones), the high child (code bit 1) the rest (the extent without that bit).
// Children have width w-1. A node none of whose axes splits at its width is not duplicated: its
// width drops until one does ("branch on need"). So a 320x320x40 root (extents 319, 319, 39,
// width 9) splits only in x and y: four children, and child 001 (z low, y low, x high) has the
// extents 63, 255 and 39.
//
// The children of a node partition its samples; the leaves partition the volume's samples.

#include <array>
#include <cstdint>
#include <utility>
#include <vector>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Sample indices [origin, origin + size) along i, j, k.
struct BonoBox {
  std::array<std::int64_t, 3> origin{};
  std::array<std::int64_t, 3> size{};

  [[nodiscard]] bool empty() const { return size[0] <= 0 || size[1] <= 0 || size[2] <= 0; }
  [[nodiscard]] std::int64_t sample_count() const {
    return empty() ? 0 : size[0] * size[1] * size[2];
  }
  /// True when the boxes share at least one sample.
  [[nodiscard]] bool overlaps(const BonoBox& other) const {
    for (int a = 0; a < 3; ++a) {
      if (origin[a] >= other.origin[a] + other.size[a]) return false;
      if (other.origin[a] >= origin[a] + size[a]) return false;
    }
    return !empty() && !other.empty();
  }
  [[nodiscard]] bool contains(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return i >= origin[0] && j >= origin[1] && k >= origin[2] && i < origin[0] + size[0] &&
           j < origin[1] + size[1] && k < origin[2] + size[2];
  }
  friend bool operator==(const BonoBox&, const BonoBox&) = default;
};

/// Construction options of a BonoOctree.
struct BonoOptions {
  /// Stop splitting a node once every axis has at most this many samples (>= 1).
  std::int64_t leaf_size = 8;
};

/// The result of one BONO split: up to eight children, in increasing code order.
struct BonoSplit {
  std::array<BonoBox, 8> boxes{};
  std::array<std::uint8_t, 8> codes{};
  int count = 0;
  /// Bit width of the children.
  int child_bits = 0;
};

class BonoOctree {
 public:
  struct Node {
    /// The samples this node owns.
    BonoBox box;
    /// Position in the parent, bits [z, y, x] (the seed's code); 0 for the root.
    std::uint8_t code = 0;
    /// Bit width of the node's extents (every extent < 2^bits).
    std::uint8_t bits = 0;
    std::uint8_t child_count = 0;
    /// Children are nodes()[first_child .. first_child + child_count).
    std::uint32_t first_child = 0;
    /// Range of the samples the node's CELLS touch: the box extended by one sample on the high
    /// side of each axis (clamped to the volume). For a leaf: a cell whose lower corner is in
    /// the box can cross iso value v only if min <= v <= max.
    float min = 0;
    float max = 0;

    [[nodiscard]] bool is_leaf() const { return child_count == 0; }
  };
  using Options = BonoOptions;

  /// Octree of a volume with min/max per node. Linear in the samples. Instantiated for float,
  /// double, std::uint8_t, std::int16_t, std::uint16_t and std::uint32_t (values read as float).
  /// Throws InputError for an empty volume, values/dims mismatch or leaf_size < 1.
  template <class T>
  static BonoOctree build(const Grid<T>& volume, const Options& options = {});
  /// Structure only (min = max = 0), e.g. for the seed's tables 4 and 5.
  static BonoOctree build_geometry(const std::array<std::int64_t, 3>& dims,
                                   const Options& options = {});

  /// Splits `box` whose extents are all < 2^bits under the seed's rule. Drops the width until an
  /// axis splits; count = 0 only when the box is a single sample. Used by split-and-merge.
  [[nodiscard]] static BonoSplit split(const BonoBox& box, int bits);
  /// Bit length of the largest extent (size - 1) of `dims`: the root's width.
  [[nodiscard]] static int root_bits(const std::array<std::int64_t, 3>& dims);

  /// nodes()[0] is the root; every node's children follow it (breadth-first order).
  [[nodiscard]] const std::vector<Node>& nodes() const { return nodes_; }
  [[nodiscard]] const Node& root() const { return nodes_.front(); }
  [[nodiscard]] const std::array<std::int64_t, 3>& dims() const { return dims_; }
  [[nodiscard]] std::size_t leaf_count() const { return leaf_count_; }
  /// The seed's extents: size - 1 per axis.
  [[nodiscard]] std::array<std::int64_t, 3> extent(const Node& node) const {
    return {node.box.size[0] - 1, node.box.size[1] - 1, node.box.size[2] - 1};
  }
  /// The child of `node` with position code `code`, or nullptr when there is none.
  [[nodiscard]] const Node* child(const Node& node, std::uint8_t code) const {
    for (std::uint32_t c = 0; c < node.child_count; ++c) {
      const Node& n = nodes_[node.first_child + c];
      if (n.code == code) return &n;
    }
    return nullptr;
  }

  /// Calls fn(const Node&) for each leaf with min <= iso_hi && max >= iso_lo, i.e. each leaf
  /// that may hold a crossing of some value in [iso_lo, iso_hi]; skips whole subtrees that
  /// cannot. Leaves come in depth-first, increasing code order.
  template <class Fn>
  void for_each_leaf_in_range(float iso_lo, float iso_hi, Fn&& fn) const {
    visit([&](const Node& n) { return n.min <= iso_hi && n.max >= iso_lo; }, fn);
  }

  /// Spatial index: calls fn(const Node&) for each leaf whose box shares a sample with `query`.
  template <class Fn>
  void for_each_leaf_overlapping(const BonoBox& query, Fn&& fn) const {
    visit([&](const Node& n) { return n.box.overlaps(query); }, fn);
  }

 private:
  template <class Pred, class Fn>
  void visit(Pred&& pred, Fn& fn) const {
    if (nodes_.empty()) return;
    std::vector<std::uint32_t> stack;
    stack.reserve(64);
    stack.push_back(0);
    while (!stack.empty()) {
      const Node& n = nodes_[stack.back()];
      stack.pop_back();
      if (!pred(n)) continue;
      if (n.child_count == 0) {
        fn(n);
        continue;
      }
      for (std::uint32_t c = n.child_count; c-- > 0;)
        stack.push_back(n.first_child + c);
    }
  }

  void build_structure(const std::array<std::int64_t, 3>& dims, const Options& options);

  std::array<std::int64_t, 3> dims_{};
  std::vector<Node> nodes_;
  std::size_t leaf_count_ = 0;
};

}  // namespace bisturi
