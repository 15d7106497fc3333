// Segmentation (seed section 2.2.1): thresholds and windows, connected components (6 vs 26,
// against a brute-force flood fill), region growing along a tube, 3-D split-and-merge on boxes
// plus noise, label indicators. Randomness: std::mt19937, fixed seeds, plain modulo.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <iostream>
#include <random>
#include <set>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/segmentation.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {
namespace {

using Dims = std::array<std::int64_t, 3>;

VolumeGeometry odd_geometry(const Dims& d) {
  VolumeGeometry g;
  g.dims = d;
  g.spacing = {0.7, 0.8, 2.5};
  g.origin = {-100.0, 20.0, 3.0};
  g.direction = glm::dmat3(0, 1, 0, -1, 0, 0, 0, 0, 1);
  return g;
}

void expect_same_geometry(const VolumeGeometry& a, const VolumeGeometry& b) {
  EXPECT_EQ(a.dims, b.dims);
  EXPECT_EQ(a.spacing, b.spacing);
  EXPECT_EQ(a.origin, b.origin);
  EXPECT_EQ(a.direction, b.direction);
}

Volume constant_volume(const Dims& d, float value) {
  Volume v;
  v.geometry = odd_geometry(d);
  v.values.assign(v.geometry.voxel_count(), value);
  return v;
}

Grid<std::uint8_t> empty_mask(const Dims& d) {
  Grid<std::uint8_t> m;
  m.geometry = odd_geometry(d);
  m.values.assign(m.geometry.voxel_count(), 0);
  return m;
}

TEST(Threshold, WindowAndInclusiveBounds) {
  const IntensityRange w = window_range(40.0F, 400.0F);  // soft-tissue window
  EXPECT_EQ(w.lo, -160.0F);
  EXPECT_EQ(w.hi, 240.0F);
  EXPECT_THROW((void)window_range(0.0F, -1.0F), InputError);

  Volume v = constant_volume({4, 3, 2}, 0.0F);
  for (std::size_t i = 0; i < v.values.size(); ++i)
    v.values[i] = static_cast<float>(i) * 20.0F - 200.0F;
  const Grid<std::uint8_t> m = threshold(v, w);
  expect_same_geometry(m.geometry, v.geometry);
  for (std::size_t i = 0; i < v.values.size(); ++i) {
    EXPECT_EQ(m.values[i], (v.values[i] >= -160.0F && v.values[i] <= 240.0F) ? 1 : 0) << i;
  }
  EXPECT_EQ(m.values[2], 1);   // -160 is inside
  EXPECT_EQ(m.values[22], 1);  // 240 is inside
  EXPECT_THROW((void)threshold(v, 5.0F, 4.0F), InputError);
}

// Brute-force labelling: flood fill from each unlabelled voxel in memory order.
std::vector<std::uint32_t> brute_labels(const Grid<std::uint8_t>& m, Connectivity c) {
  const auto& d = m.geometry.dims;
  std::vector<std::uint32_t> labels(m.values.size(), 0);
  std::uint32_t next = 0;
  for (std::int64_t k0 = 0; k0 < d[2]; ++k0) {
    for (std::int64_t j0 = 0; j0 < d[1]; ++j0) {
      for (std::int64_t i0 = 0; i0 < d[0]; ++i0) {
        const std::size_t s = m.geometry.linear_index(i0, j0, k0);
        if (m.values[s] == 0 || labels[s] != 0) continue;
        labels[s] = ++next;
        std::vector<Dims> stack{{i0, j0, k0}};
        while (!stack.empty()) {
          const Dims p = stack.back();
          stack.pop_back();
          for (std::int64_t dk = -1; dk <= 1; ++dk) {
            for (std::int64_t dj = -1; dj <= 1; ++dj) {
              for (std::int64_t di = -1; di <= 1; ++di) {
                const int manhattan = static_cast<int>(std::abs(di) + std::abs(dj) + std::abs(dk));
                if (manhattan == 0) continue;
                if (c == Connectivity::Six && manhattan > 1) continue;
                const Dims q{p[0] + di, p[1] + dj, p[2] + dk};
                if (!m.geometry.contains(q[0], q[1], q[2])) continue;
                const std::size_t qi = m.geometry.linear_index(q[0], q[1], q[2]);
                if (m.values[qi] == 0 || labels[qi] != 0) continue;
                labels[qi] = next;
                stack.push_back(q);
              }
            }
          }
        }
      }
    }
  }
  return labels;
}

TEST(Components, DiagonalBlobsSixVersusTwentySix) {
  Grid<std::uint8_t> m = empty_mask({10, 10, 10});
  // Blob A: 2x2x2 at (1..2)^3; blob B touches it at one corner: 2x2x2 at (3..4)^3.
  // Blob C: a 3x1x1 bar at (7..9, 8, 8), apart from A and B.
  for (std::int64_t k = 1; k <= 2; ++k)
    for (std::int64_t j = 1; j <= 2; ++j)
      for (std::int64_t i = 1; i <= 2; ++i)
        m.at(i, j, k) = 1;
  for (std::int64_t k = 3; k <= 4; ++k)
    for (std::int64_t j = 3; j <= 4; ++j)
      for (std::int64_t i = 3; i <= 4; ++i)
        m.at(i, j, k) = 1;
  for (std::int64_t i = 7; i <= 9; ++i)
    m.at(i, 8, 8) = 1;
  // Blob D: the voxel (9, 9, 9), which shares only an edge with C's (9, 8, 8).
  m.at(9, 9, 9) = 1;

  const Components six = label_components(m, Connectivity::Six);
  const Components all = label_components(m, Connectivity::TwentySix);
  EXPECT_EQ(six.labels.label_count, 4U);
  EXPECT_EQ(all.labels.label_count, 2U);
  expect_same_geometry(six.labels.geometry, m.geometry);

  ASSERT_EQ(six.stats.size(), 4U);
  EXPECT_EQ(six.stats[0].label, 1U);
  EXPECT_EQ(six.stats[0].voxel_count, 8);
  EXPECT_EQ(six.stats[0].first_voxel, (Dims{1, 1, 1}));
  EXPECT_EQ(six.stats[0].bounds.origin, (Dims{1, 1, 1}));
  EXPECT_EQ(six.stats[0].bounds.size, (Dims{2, 2, 2}));
  EXPECT_EQ(six.stats[1].first_voxel, (Dims{3, 3, 3}));
  EXPECT_EQ(six.stats[2].voxel_count, 3);
  EXPECT_EQ(six.stats[2].bounds.origin, (Dims{7, 8, 8}));
  EXPECT_EQ(six.stats[2].bounds.size, (Dims{3, 1, 1}));
  EXPECT_EQ(six.stats[3].voxel_count, 1);
  EXPECT_EQ(six.labels.at(9, 9, 9), 4U);

  ASSERT_EQ(all.stats.size(), 2U);
  EXPECT_EQ(all.stats[0].voxel_count, 16);
  EXPECT_EQ(all.stats[0].bounds.origin, (Dims{1, 1, 1}));
  EXPECT_EQ(all.stats[0].bounds.size, (Dims{4, 4, 4}));
  EXPECT_EQ(all.stats[1].voxel_count, 4);
  EXPECT_EQ(all.stats[1].bounds.origin, (Dims{7, 8, 8}));
  EXPECT_EQ(all.stats[1].bounds.size, (Dims{3, 2, 2}));
  EXPECT_EQ(all.labels.at(4, 4, 4), 1U);
  EXPECT_EQ(all.labels.at(0, 0, 0), 0U);

  // min_voxels drops the small ones and keeps the order of the rest.
  const Components big = label_components(m, Connectivity::Six, {.min_voxels = 4});
  EXPECT_EQ(big.labels.label_count, 2U);
  EXPECT_EQ(big.labels.at(3, 3, 3), 2U);
  EXPECT_EQ(big.labels.at(8, 8, 8), 0U);
  EXPECT_EQ(big.stats[1].label, 2U);
}

TEST(Components, MatchBruteForceOnRandomMasks) {
  std::mt19937 rng(11);
  for (int round = 0; round < 30; ++round) {
    const Dims d{1 + static_cast<std::int64_t>(rng() % 25),
                 1 + static_cast<std::int64_t>(rng() % 25),
                 1 + static_cast<std::int64_t>(rng() % 25)};
    Grid<std::uint8_t> m = empty_mask(d);
    const auto density = static_cast<std::uint32_t>(20 + rng() % 50);
    for (auto& v : m.values)
      v = (rng() % 100) < density ? 1 : 0;
    for (Connectivity c : {Connectivity::Six, Connectivity::TwentySix}) {
      const Components got = label_components(m, c);
      const std::vector<std::uint32_t> want = brute_labels(m, c);
      ASSERT_EQ(got.labels.values.size(), want.size());
      for (std::size_t i = 0; i < want.size(); ++i)
        ASSERT_EQ(got.labels.values[i], want[i]) << i;
      std::vector<std::int64_t> counts(got.stats.size() + 1, 0);
      for (std::uint32_t l : want)
        ++counts[l];
      ASSERT_EQ(got.stats.size(), got.labels.label_count);
      for (const ComponentStats& s : got.stats)
        EXPECT_EQ(s.voxel_count, counts[s.label]);
    }
  }
}

// Not an assertion: CCL time on a 256^3 mask of random balls, printed for the record.
TEST(Components, Time256) {
  const Dims d{256, 256, 256};
  Grid<std::uint8_t> m = empty_mask(d);
  std::mt19937 rng(7);
  for (int b = 0; b < 300; ++b) {
    const std::int64_t ci = rng() % 256, cj = rng() % 256, ck = rng() % 256, r = 2 + rng() % 10;
    for (std::int64_t k = std::max<std::int64_t>(0, ck - r);
         k <= std::min<std::int64_t>(255, ck + r); ++k)
      for (std::int64_t j = std::max<std::int64_t>(0, cj - r);
           j <= std::min<std::int64_t>(255, cj + r); ++j)
        for (std::int64_t i = std::max<std::int64_t>(0, ci - r);
             i <= std::min<std::int64_t>(255, ci + r); ++i)
          if ((i - ci) * (i - ci) + (j - cj) * (j - cj) + (k - ck) * (k - ck) <= r * r)
            m.at(i, j, k) = 1;
  }
  for (Connectivity c : {Connectivity::Six, Connectivity::TwentySix}) {
    const auto t0 = std::chrono::steady_clock::now();
    const Components got = label_components(m, c);
    const auto t1 = std::chrono::steady_clock::now();
    std::cout << "[ timing ] CCL 256^3 (" << (c == Connectivity::Six ? 6 : 26)
              << "): " << std::chrono::duration<double, std::milli>(t1 - t0).count() << " ms, "
              << got.labels.label_count << " components\n";
    EXPECT_GT(got.labels.label_count, 0U);
  }
  // Random noise (many short runs): the worst case for a run-based labelling.
  for (auto& v : m.values)
    v = (rng() % 2) != 0 ? 1 : 0;
  const auto t0 = std::chrono::steady_clock::now();
  const Components noise = label_components(m, Connectivity::TwentySix);
  const auto t1 = std::chrono::steady_clock::now();
  std::cout << "[ timing ] CCL 256^3 50% noise (26): "
            << std::chrono::duration<double, std::milli>(t1 - t0).count() << " ms, "
            << noise.labels.label_count << " components\n";
}

// A bent tube of value 300 in a background of 0, and a second tube beyond a one-voxel gap.
Volume tube_volume() {
  Volume v = constant_volume({40, 30, 20}, 0.0F);
  for (std::int64_t i = 2; i < 30; ++i)  // along x at (j, k) = (5..6, 5..6)
    for (std::int64_t j = 5; j <= 6; ++j)
      for (std::int64_t k = 5; k <= 6; ++k)
        v.at(i, j, k) = 300.0F;
  for (std::int64_t j = 5; j < 25; ++j)  // then along y at i = 28..29
    for (std::int64_t i = 28; i <= 29; ++i)
      for (std::int64_t k = 5; k <= 6; ++k)
        v.at(i, j, k) = 300.0F;
  for (std::int64_t i = 31; i < 38; ++i)  // beyond the gap at i = 30
    for (std::int64_t j = 5; j <= 6; ++j)
      for (std::int64_t k = 5; k <= 6; ++k)
        v.at(i, j, k) = 310.0F;
  return v;
}

TEST(RegionGrow, FollowsTheTubeAndStopsAtTheGap) {
  const Volume v = tube_volume();
  const Grid<std::uint8_t> m = region_grow(v, {3, 5, 5}, 200.0F, 400.0F, Connectivity::Six);
  expect_same_geometry(m.geometry, v.geometry);
  std::int64_t count = 0;
  for (std::uint8_t x : m.values)
    count += x;
  EXPECT_EQ(count, 28 * 4 + 20 * 4 - 8);  // two segments sharing a 2x2x2 corner
  EXPECT_EQ(m.at(29, 24, 6), 1);          // end of the bend
  EXPECT_EQ(m.at(31, 5, 5), 0);           // beyond the gap
  EXPECT_EQ(m.at(0, 0, 0), 0);
  // Whole thing = union of both tube segments, overlapping in 2x2x2 voxels.
  std::int64_t expected = 0;
  for (std::size_t i = 0; i < v.values.size(); ++i)
    expected += v.values[i] == 300.0F ? 1 : 0;
  EXPECT_EQ(count, expected);
}

TEST(RegionGrow, DiagonalStepNeedsTwentySix) {
  Volume v = constant_volume({10, 10, 10}, 0.0F);
  for (std::int64_t t = 0; t < 8; ++t)
    v.at(t, t, t) = 1.0F;  // a corner-connected line
  EXPECT_EQ(region_grow(v, {0, 0, 0}, 0.5F, 1.5F, Connectivity::Six)
                .values[v.geometry.linear_index(1, 1, 1)],
            0);
  const Grid<std::uint8_t> m = region_grow(v, {0, 0, 0}, 0.5F, 1.5F, Connectivity::TwentySix);
  EXPECT_EQ(m.at(7, 7, 7), 1);
}

TEST(RegionGrow, BadSeedsNameTheSeedAndTheValue) {
  const Volume v = tube_volume();
  try {
    (void)region_grow(v, {40, 0, 0}, 200.0F, 400.0F, Connectivity::Six);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("seed (40, 0, 0)"), std::string::npos) << e.what();
  }
  try {
    (void)region_grow(v, {1, 2, 3}, 200.0F, 400.0F, Connectivity::Six);
    FAIL() << "no exception";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("seed (1, 2, 3)"), std::string::npos) << what;
    EXPECT_NE(what.find("value 0"), std::string::npos) << what;
  }
}

// Boxes of 100 and 200 in a background of 0, uniform noise of +-3; tolerance 10.
Volume boxes_with_noise(std::mt19937& rng) {
  Volume v = constant_volume({37, 29, 23}, 0.0F);
  for (std::int64_t k = 0; k < 23; ++k) {
    for (std::int64_t j = 0; j < 29; ++j) {
      for (std::int64_t i = 0; i < 37; ++i) {
        float base = 0.0F;
        if (i >= 4 && i < 15 && j >= 3 && j < 20 && k >= 2 && k < 12) base = 100.0F;
        if (i >= 20 && i < 33 && j >= 10 && j < 27 && k >= 8 && k < 21) base = 200.0F;
        v.at(i, j, k) = base + static_cast<float>(rng() % 61) / 10.0F - 3.0F;
      }
    }
  }
  return v;
}

TEST(SplitAndMerge, RecoversBoxesUnderNoise) {
  std::mt19937 rng(2024);
  const Volume v = boxes_with_noise(rng);
  const LabelVolume labels = split_and_merge(v, {.tolerance = 10.0F});
  expect_same_geometry(labels.geometry, v.geometry);
  ASSERT_EQ(labels.label_count, 3U);
  // Labels follow first voxels: background first (voxel 0), then box A, then box B.
  EXPECT_EQ(labels.at(0, 0, 0), 1U);
  EXPECT_EQ(labels.at(4, 3, 2), 2U);
  EXPECT_EQ(labels.at(20, 10, 8), 3U);
  for (std::int64_t k = 0; k < 23; ++k) {
    for (std::int64_t j = 0; j < 29; ++j) {
      for (std::int64_t i = 0; i < 37; ++i) {
        const float x = v.at(i, j, k);
        const std::uint32_t want = x > 150.0F ? 3U : (x > 50.0F ? 2U : 1U);
        ASSERT_EQ(labels.at(i, j, k), want) << i << "," << j << "," << k;
      }
    }
  }
  // Deterministic.
  EXPECT_EQ(split_and_merge(v, {.tolerance = 10.0F}).values, labels.values);
}

TEST(SplitAndMerge, SmallRegionsJoinTheirClosestNeighbour) {
  std::mt19937 rng(1);
  Volume v = boxes_with_noise(rng);
  v.at(30, 2, 2) = 60.0F;  // an outlier in the background
  const LabelVolume plain = split_and_merge(v, {.tolerance = 10.0F});
  EXPECT_EQ(plain.label_count, 4U);
  const LabelVolume cleaned = split_and_merge(v, {.tolerance = 10.0F, .min_region_voxels = 2});
  EXPECT_EQ(cleaned.label_count, 3U);
  EXPECT_EQ(cleaned.at(30, 2, 2), cleaned.at(0, 0, 0));
}

TEST(SplitAndMerge, ConstantAndSingleVoxelVolumes) {
  EXPECT_EQ(split_and_merge(constant_volume({13, 7, 5}, 3.0F)).label_count, 1U);
  EXPECT_EQ(split_and_merge(constant_volume({1, 1, 1}, 3.0F)).label_count, 1U);
  Volume ramp = constant_volume({8, 1, 1}, 0.0F);
  for (std::int64_t i = 0; i < 8; ++i)
    ramp.at(i, 0, 0) = static_cast<float>(i);
  // Tolerance 1: greedy merging pairs neighbours in memory order: {0,1}, {2,3}, ...
  const LabelVolume l = split_and_merge(ramp, {.tolerance = 1.0F});
  EXPECT_EQ(l.label_count, 4U);
  EXPECT_THROW((void)split_and_merge(ramp, {.tolerance = -1.0F}), InputError);
}

TEST(LabelIndicator, OneInsideZeroOutside) {
  LabelVolume l;
  l.geometry = odd_geometry({3, 2, 2});
  l.values = {0, 1, 2, 2, 1, 0, 0, 0, 2, 2, 2, 1};
  l.label_count = 2;
  const Grid<float> g = label_indicator(l, 2);
  const Volume v = label_indicator_volume(l, 1);
  expect_same_geometry(g.geometry, l.geometry);
  expect_same_geometry(v.geometry, l.geometry);
  for (std::size_t i = 0; i < l.values.size(); ++i) {
    EXPECT_EQ(g.values[i], l.values[i] == 2 ? 1.0F : 0.0F);
    EXPECT_EQ(v.values[i], l.values[i] == 1 ? 1.0F : 0.0F);
  }
}

}  // namespace
}  // namespace bisturi
