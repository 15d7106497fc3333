// BONO octree (seed section 2.2.1.1): the seed's tables 4 and 5 (a 320x320x40 root splits only in
// x and y; child 001 has the extents 63, 255 and 39) and the levels below them; leaves partition
// the samples; node min/max against brute force; the range and overlap queries against brute
// force. Randomness: std::mt19937 with fixed seeds and plain modulo (no std::*_distribution).

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <random>
#include <set>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/bono_octree.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {
namespace {

using Dims = std::array<std::int64_t, 3>;
using Node = BonoOctree::Node;

const Node& child_with_code(const BonoOctree& tree, const Node& parent, std::uint8_t code) {
  const Node* c = tree.child(parent, code);
  if (c == nullptr) throw std::runtime_error("no child with code " + std::to_string(code));
  return *c;
}

std::vector<std::uint8_t> child_codes(const BonoOctree& tree, const Node& parent) {
  std::vector<std::uint8_t> codes;
  for (std::uint32_t c = 0; c < parent.child_count; ++c) {
    codes.push_back(tree.nodes()[parent.first_child + c].code);
  }
  return codes;
}

// Table 4: extents 319 = 100111111, 319, 39 = 000100111 in the root's 9 bits: only x and y have
// the most significant bit set, so the root has four children ([z, y, x] = 000, 001, 010, 011).
TEST(BonoOctreeTable4, RootSplitsOnlyInXAndY) {
  const BonoOctree tree = BonoOctree::build_geometry({320, 320, 40}, {.leaf_size = 32});
  const Node& root = tree.root();
  EXPECT_EQ(tree.extent(root), (Dims{319, 319, 39}));
  EXPECT_EQ(root.bits, 9);
  EXPECT_EQ(BonoOctree::root_bits({320, 320, 40}), 9);
  EXPECT_EQ(root.child_count, 4);
  EXPECT_EQ(child_codes(tree, root), (std::vector<std::uint8_t>{0b000, 0b001, 0b010, 0b011}));
  // Low children: a string of eight 1s (255); high children: the extent without its top bit.
  EXPECT_EQ(tree.extent(child_with_code(tree, root, 0b000)), (Dims{255, 255, 39}));
  EXPECT_EQ(tree.extent(child_with_code(tree, root, 0b010)), (Dims{255, 63, 39}));
  EXPECT_EQ(tree.extent(child_with_code(tree, root, 0b011)), (Dims{63, 63, 39}));
  EXPECT_EQ(child_with_code(tree, root, 0b011).box.origin, (Dims{256, 256, 0}));
  EXPECT_EQ(child_with_code(tree, root, 0b010).box.origin, (Dims{0, 256, 0}));
  for (std::uint32_t c = 0; c < root.child_count; ++c) {
    EXPECT_EQ(tree.nodes()[root.first_child + c].bits, 8);
  }
}

// Table 5: child 001 (z low, y low, x high) has the extents 63 (00111111), 255 (11111111) and 39
// (00100111).
TEST(BonoOctreeTable5, Child001Extents) {
  const BonoOctree tree = BonoOctree::build_geometry({320, 320, 40}, {.leaf_size = 32});
  const Node& c001 = child_with_code(tree, tree.root(), 0b001);
  EXPECT_EQ(tree.extent(c001), (Dims{63, 255, 39}));
  EXPECT_EQ(c001.box.origin, (Dims{256, 0, 0}));
  EXPECT_EQ(c001.box.size, (Dims{64, 256, 40}));
}

// The next levels, by the same rule in 8 bits and below.
TEST(BonoOctreeTable5, NextLevels) {
  const BonoOctree tree = BonoOctree::build_geometry({320, 320, 40}, {.leaf_size = 32});
  const Node& root = tree.root();
  // 001 (63, 255, 39) in 8 bits: only y (11111111) has bit 7 set: two children.
  const Node& c001 = child_with_code(tree, root, 0b001);
  EXPECT_EQ(child_codes(tree, c001), (std::vector<std::uint8_t>{0b000, 0b010}));
  EXPECT_EQ(tree.extent(child_with_code(tree, c001, 0b000)), (Dims{63, 127, 39}));
  EXPECT_EQ(tree.extent(child_with_code(tree, c001, 0b010)), (Dims{63, 127, 39}));
  EXPECT_EQ(child_with_code(tree, c001, 0b010).box.origin, (Dims{256, 128, 0}));
  // 000 (255, 255, 39): x and y split into 127s.
  const Node& c000 = child_with_code(tree, root, 0b000);
  EXPECT_EQ(child_codes(tree, c000), (std::vector<std::uint8_t>{0b000, 0b001, 0b010, 0b011}));
  for (std::uint32_t c = 0; c < c000.child_count; ++c) {
    EXPECT_EQ(tree.extent(tree.nodes()[c000.first_child + c]), (Dims{127, 127, 39}));
  }
  // 011 (63, 63, 39): no axis has bit 7 or bit 6 set, so the node branches only when the width
  // reaches 6 bits, where 63 = 111111 and 39 = 100111 all split: eight children.
  const Node& c011 = child_with_code(tree, root, 0b011);
  ASSERT_EQ(c011.child_count, 8);
  EXPECT_EQ(tree.extent(child_with_code(tree, c011, 0b000)), (Dims{31, 31, 31}));
  EXPECT_EQ(tree.extent(child_with_code(tree, c011, 0b111)), (Dims{31, 31, 7}));
  EXPECT_EQ(tree.extent(child_with_code(tree, c011, 0b100)), (Dims{31, 31, 7}));
  EXPECT_EQ(child_with_code(tree, c011, 0b111).box.origin, (Dims{288, 288, 32}));
  EXPECT_EQ(child_with_code(tree, c011, 0b000).bits, 5);
  // 000/000 (127, 127, 39) in 7 bits: 127 = 1111111 splits, 39 = 0100111 does not.
  const Node& c000000 = child_with_code(tree, c000, 0b000);
  EXPECT_EQ(child_codes(tree, c000000), (std::vector<std::uint8_t>{0b000, 0b001, 0b010, 0b011}));
  EXPECT_EQ(tree.extent(child_with_code(tree, c000000, 0b011)), (Dims{63, 63, 39}));
}

// The rule on every internal node: an axis splits iff the top bit of its extent in the width at
// which the node branches is 1; low = all ones below it, high = the extent without it.
void expect_seed_rule(const BonoOctree& tree) {
  for (const Node& n : tree.nodes()) {
    if (n.is_leaf()) continue;
    const auto e = tree.extent(n);
    const int child_bits = tree.nodes()[n.first_child].bits;
    const std::int64_t top = std::int64_t{1} << child_bits;
    for (int a = 0; a < 3; ++a)
      EXPECT_LT(e[a], 2 * top);
    for (std::uint32_t c = 0; c < n.child_count; ++c) {
      const Node& ch = tree.nodes()[n.first_child + c];
      EXPECT_EQ(ch.bits, child_bits);
      const auto ce = tree.extent(ch);
      for (int a = 0; a < 3; ++a) {
        const bool splits = (e[a] & top) != 0;
        const bool high = ((ch.code >> a) & 1) != 0;
        if (!splits) {
          EXPECT_FALSE(high);
          EXPECT_EQ(ce[a], e[a]);
          EXPECT_EQ(ch.box.origin[a], n.box.origin[a]);
        } else if (!high) {
          EXPECT_EQ(ce[a], top - 1);
          EXPECT_EQ(ch.box.origin[a], n.box.origin[a]);
        } else {
          EXPECT_EQ(ce[a], e[a] - top);
          EXPECT_EQ(ch.box.origin[a], n.box.origin[a] + top);
        }
      }
    }
    // Some axis splits at the branching width; none at any wider one (branch on need).
    EXPECT_TRUE((e[0] | e[1] | e[2]) & top);
    EXPECT_LT(e[0] | e[1] | e[2], 2 * top);
    EXPECT_LE(child_bits + 1, n.bits);
  }
}

// Every sample in exactly one leaf; leaves no larger than leaf_size; children follow parents.
void expect_partition(const BonoOctree& tree, const Dims& dims, std::int64_t leaf_size) {
  std::vector<int> hits(static_cast<std::size_t>(dims[0] * dims[1] * dims[2]), 0);
  std::size_t leaves = 0;
  for (std::size_t index = 0; index < tree.nodes().size(); ++index) {
    const Node& n = tree.nodes()[index];
    if (!n.is_leaf()) {
      EXPECT_GT(n.first_child, index);
      continue;
    }
    ++leaves;
    for (int a = 0; a < 3; ++a) {
      EXPECT_GE(n.box.size[a], 1);
      EXPECT_LE(n.box.size[a], leaf_size);
    }
    for (std::int64_t k = n.box.origin[2]; k < n.box.origin[2] + n.box.size[2]; ++k) {
      for (std::int64_t j = n.box.origin[1]; j < n.box.origin[1] + n.box.size[1]; ++j) {
        for (std::int64_t i = n.box.origin[0]; i < n.box.origin[0] + n.box.size[0]; ++i) {
          ASSERT_TRUE(i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2]);
          ++hits[static_cast<std::size_t>(i + dims[0] * (j + dims[1] * k))];
        }
      }
    }
  }
  EXPECT_EQ(leaves, tree.leaf_count());
  EXPECT_EQ(std::count(hits.begin(), hits.end(), 1), static_cast<std::ptrdiff_t>(hits.size()));
}

TEST(BonoOctree, LeavesPartitionTheSamples) {
  const std::vector<Dims> cases = {{1, 1, 1},    {2, 1, 1},    {320, 320, 40}, {17, 5, 33},
                                   {64, 64, 64}, {65, 3, 129}, {9, 9, 9},      {1, 100, 1}};
  for (const Dims& d : cases) {
    for (std::int64_t leaf : {1, 2, 3, 8, 16}) {
      if (leaf < 4 && d[0] * d[1] * d[2] > 300000) continue;
      SCOPED_TRACE(std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]) +
                   " leaf " + std::to_string(leaf));
      const BonoOctree tree = BonoOctree::build_geometry(d, {.leaf_size = leaf});
      expect_partition(tree, d, leaf);
      expect_seed_rule(tree);
      EXPECT_EQ(tree.dims(), d);
    }
  }
}

TEST(BonoOctree, RandomDimensionsFollowTheRule) {
  std::mt19937 rng(5);
  for (int round = 0; round < 40; ++round) {
    const Dims d{1 + static_cast<std::int64_t>(rng() % 70),
                 1 + static_cast<std::int64_t>(rng() % 70),
                 1 + static_cast<std::int64_t>(rng() % 70)};
    const std::int64_t leaf = 1 + static_cast<std::int64_t>(rng() % 9);
    SCOPED_TRACE(std::to_string(d[0]) + "x" + std::to_string(d[1]) + "x" + std::to_string(d[2]) +
                 " leaf " + std::to_string(leaf));
    const BonoOctree tree = BonoOctree::build_geometry(d, {.leaf_size = leaf});
    expect_partition(tree, d, leaf);
    expect_seed_rule(tree);
  }
}

template <class T>
Grid<T> random_grid(const Dims& d, std::mt19937& rng, std::uint32_t modulo) {
  Grid<T> g;
  g.geometry.dims = d;
  g.values.resize(g.geometry.voxel_count());
  for (auto& v : g.values)
    v = static_cast<T>(rng() % modulo);
  return g;
}

// Range of the samples a node's cells touch, by brute force.
template <class T>
std::pair<float, float> brute_range(const Grid<T>& g, const BonoBox& box) {
  const auto& d = g.geometry.dims;
  float mn = INFINITY;
  float mx = -INFINITY;
  for (std::int64_t k = box.origin[2]; k < std::min(box.origin[2] + box.size[2] + 1, d[2]); ++k) {
    for (std::int64_t j = box.origin[1]; j < std::min(box.origin[1] + box.size[1] + 1, d[1]); ++j) {
      for (std::int64_t i = box.origin[0]; i < std::min(box.origin[0] + box.size[0] + 1, d[0]);
           ++i) {
        mn = std::min(mn, static_cast<float>(g.at(i, j, k)));
        mx = std::max(mx, static_cast<float>(g.at(i, j, k)));
      }
    }
  }
  return {mn, mx};
}

template <class T>
void check_min_max(std::uint32_t modulo) {
  std::mt19937 rng(17);
  for (int round = 0; round < 12; ++round) {
    const Dims d{1 + static_cast<std::int64_t>(rng() % 40),
                 1 + static_cast<std::int64_t>(rng() % 40),
                 1 + static_cast<std::int64_t>(rng() % 40)};
    const std::int64_t leaf = 1 + static_cast<std::int64_t>(rng() % 8);
    const Grid<T> g = random_grid<T>(d, rng, modulo);
    const BonoOctree tree = BonoOctree::build(g, {.leaf_size = leaf});
    for (const Node& n : tree.nodes()) {
      const auto [mn, mx] = brute_range(g, n.box);
      ASSERT_EQ(n.min, mn);
      ASSERT_EQ(n.max, mx);
    }
  }
}

TEST(BonoOctree, MinMaxMatchBruteForce) {
  check_min_max<float>(1000);
  check_min_max<std::uint8_t>(256);
  check_min_max<std::uint32_t>(70000);
  check_min_max<std::int16_t>(3000);
}

// Smooth random field: a few Gaussian-ish blobs, so that many leaves are far from an iso value.
Grid<float> blob_field(const Dims& d, std::mt19937& rng) {
  Grid<float> g;
  g.geometry.dims = d;
  g.values.resize(g.geometry.voxel_count());
  std::vector<std::array<double, 4>> blobs;
  for (int b = 0; b < 4; ++b) {
    blobs.push_back({static_cast<double>(rng() % static_cast<std::uint32_t>(d[0])),
                     static_cast<double>(rng() % static_cast<std::uint32_t>(d[1])),
                     static_cast<double>(rng() % static_cast<std::uint32_t>(d[2])),
                     4.0 + static_cast<double>(rng() % 8)});
  }
  for (std::int64_t k = 0; k < d[2]; ++k) {
    for (std::int64_t j = 0; j < d[1]; ++j) {
      for (std::int64_t i = 0; i < d[0]; ++i) {
        double v = 0;
        for (const auto& b : blobs) {
          const double x = static_cast<double>(i) - b[0];
          const double y = static_cast<double>(j) - b[1];
          const double z = static_cast<double>(k) - b[2];
          const double r2 = x * x + y * y + z * z;
          v += 100.0 * std::exp(-r2 / (2 * b[3] * b[3]));
        }
        g.at(i, j, k) = static_cast<float>(v);
      }
    }
  }
  return g;
}

TEST(BonoOctree, RangeQueryReturnsExactlyTheLeavesThatCanCross) {
  std::mt19937 rng(99);
  for (int round = 0; round < 6; ++round) {
    const Dims d{20 + static_cast<std::int64_t>(rng() % 30),
                 20 + static_cast<std::int64_t>(rng() % 30),
                 10 + static_cast<std::int64_t>(rng() % 30)};
    const Grid<float> g = blob_field(d, rng);
    const BonoOctree tree =
        BonoOctree::build(g, {.leaf_size = 1 + static_cast<std::int64_t>(rng() % 8)});
    for (const auto& [lo, hi] : std::vector<std::pair<float, float>>{
             {50.0F, 50.0F}, {10.0F, 20.0F}, {-5.0F, -1.0F}, {0.5F, 0.5F}, {90.0F, 1000.0F}}) {
      std::set<const Node*> got;
      tree.for_each_leaf_in_range(lo, hi, [&](const Node& n) {
        EXPECT_TRUE(n.is_leaf());
        EXPECT_TRUE(got.insert(&n).second);
      });
      std::set<const Node*> want;
      for (const Node& n : tree.nodes()) {
        if (n.is_leaf() && n.min <= hi && n.max >= lo) want.insert(&n);
      }
      EXPECT_EQ(got, want);
      // Every cell that crosses lo (a corner below, a corner at or above) is in a returned leaf.
      for (const Node& n : tree.nodes()) {
        if (!n.is_leaf() || got.count(&n) != 0) continue;
        for (std::int64_t k = n.box.origin[2]; k < n.box.origin[2] + n.box.size[2]; ++k) {
          for (std::int64_t j = n.box.origin[1]; j < n.box.origin[1] + n.box.size[1]; ++j) {
            for (std::int64_t i = n.box.origin[0]; i < n.box.origin[0] + n.box.size[0]; ++i) {
              if (i + 1 >= d[0] || j + 1 >= d[1] || k + 1 >= d[2]) continue;
              bool below = false;
              bool above = false;
              for (int c = 0; c < 8; ++c) {
                const float v = g.at(i + (c & 1), j + ((c >> 1) & 1), k + ((c >> 2) & 1));
                below = below || v < lo;
                above = above || v >= lo;
              }
              ASSERT_FALSE(below && above) << "cell " << i << "," << j << "," << k;
            }
          }
        }
      }
    }
  }
}

TEST(BonoOctree, RangeQuerySkipsConstantVolume) {
  Grid<float> g;
  g.geometry.dims = {33, 20, 17};
  g.values.assign(g.geometry.voxel_count(), 7.0F);
  const BonoOctree tree = BonoOctree::build(g);
  int count = 0;
  tree.for_each_leaf_in_range(8.0F, 9.0F, [&](const Node&) { ++count; });
  EXPECT_EQ(count, 0);
  tree.for_each_leaf_in_range(7.0F, 7.0F, [&](const Node&) { ++count; });
  EXPECT_EQ(static_cast<std::size_t>(count), tree.leaf_count());
  EXPECT_EQ(tree.root().min, 7.0F);
  EXPECT_EQ(tree.root().max, 7.0F);
}

TEST(BonoOctree, OverlapQueryMatchesBruteForce) {
  std::mt19937 rng(3);
  const Dims d{45, 31, 22};
  const BonoOctree tree = BonoOctree::build_geometry(d, {.leaf_size = 4});
  for (int round = 0; round < 50; ++round) {
    BonoBox q;
    for (int a = 0; a < 3; ++a) {
      q.origin[a] = static_cast<std::int64_t>(rng() % 60) - 10;
      q.size[a] = static_cast<std::int64_t>(rng() % 20);
    }
    std::set<const Node*> got;
    tree.for_each_leaf_overlapping(q, [&](const Node& n) { got.insert(&n); });
    std::set<const Node*> want;
    for (const Node& n : tree.nodes()) {
      if (!n.is_leaf()) continue;
      bool overlap = !q.empty();
      for (int a = 0; a < 3; ++a) {
        overlap = overlap && n.box.origin[a] < q.origin[a] + q.size[a] &&
                  q.origin[a] < n.box.origin[a] + n.box.size[a];
      }
      if (overlap) want.insert(&n);
    }
    EXPECT_EQ(got, want);
  }
}

TEST(BonoOctree, RejectsBadInput) {
  EXPECT_THROW((void)BonoOctree::build_geometry({0, 4, 4}), InputError);
  EXPECT_THROW((void)BonoOctree::build_geometry({4, 4, 4}, {.leaf_size = 0}), InputError);
  Grid<float> g;
  g.geometry.dims = {4, 4, 4};
  g.values.resize(10);
  EXPECT_THROW((void)BonoOctree::build(g), InputError);
}

// Not an assertion: the build time of a 256^3 float volume, printed for the record.
TEST(BonoOctree, BuildTime256) {
  const Dims d{256, 256, 256};
  Volume v;
  v.geometry.dims = d;
  v.values.resize(v.geometry.voxel_count());
  for (std::int64_t k = 0; k < d[2]; ++k) {
    for (std::int64_t j = 0; j < d[1]; ++j) {
      for (std::int64_t i = 0; i < d[0]; ++i) {
        const double x = static_cast<double>(i) - 128.0;
        const double y = static_cast<double>(j) - 128.0;
        const double z = static_cast<double>(k) - 128.0;
        v.at(i, j, k) = static_cast<float>(std::sqrt(x * x + y * y + z * z));
      }
    }
  }
  const auto t0 = std::chrono::steady_clock::now();
  const BonoOctree tree = BonoOctree::build(v);
  const auto t1 = std::chrono::steady_clock::now();
  std::size_t hits = 0;
  tree.for_each_leaf_in_range(60.0F, 60.0F, [&](const Node&) { ++hits; });
  const auto t2 = std::chrono::steady_clock::now();
  const double build_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  const double query_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  std::cout << "[ timing ] BONO build 256^3 float, leaf 8: " << build_ms << " ms, "
            << tree.nodes().size() << " nodes, " << tree.leaf_count()
            << " leaves; iso 60 query: " << hits << " leaves in " << query_ms << " ms\n";
  RecordProperty("build_ms_256", static_cast<int>(build_ms));
  EXPECT_EQ(tree.root().min, 0.0F);
  EXPECT_GT(hits, 0U);
  EXPECT_LT(hits, tree.leaf_count() / 4);
}

}  // namespace
}  // namespace bisturi
