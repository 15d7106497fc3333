// Occlusion culling's test on the CPU (OccluderDepth): what it may call hidden, and what it must
// not. Every claim is checked both ways: a box behind a surface is hidden, the same box in
// front of it, beside its outline, behind a hole in it or behind its culled back is not.

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/render/occluder_depth.h"
#include "bisturi/runtime/render/solid_levels.h"
#include "bisturi/scene/polygon_export.h"
#include "render_test_support.h"

namespace bisturi::render {
namespace {

struct Surface {
  std::vector<float> vertices;  ///< x, y, z per vertex
  std::vector<std::uint32_t> indices;
};

Surface from_solid(const Dlfl& mesh) {
  const ExportedPolygons e = export_polygons(mesh);
  Surface s;
  for (const glm::dvec3& p : e.polygons.positions) {
    s.vertices.push_back(static_cast<float>(p.x));
    s.vertices.push_back(static_cast<float>(p.y));
    s.vertices.push_back(static_cast<float>(p.z));
  }
  s.indices = triangulate(e.polygons);
  return s;
}

/// A square sheet of n x n quads in the plane z, |x|, |y| <= half, facing +z (or -z when
/// `facing_down`), without the quads whose centre lies within `hole` of the axis in x and y.
Surface sheet(double z, double half, int n, bool facing_down = false, double hole = 0.0) {
  Surface s;
  for (int j = 0; j <= n; ++j)
    for (int i = 0; i <= n; ++i) {
      s.vertices.push_back(static_cast<float>(-half + 2.0 * half * i / n));
      s.vertices.push_back(static_cast<float>(-half + 2.0 * half * j / n));
      s.vertices.push_back(static_cast<float>(z));
    }
  const auto at = [n](int i, int j) { return static_cast<std::uint32_t>(j * (n + 1) + i); };
  for (int j = 0; j < n; ++j)
    for (int i = 0; i < n; ++i) {
      const double cx = -half + 2.0 * half * (i + 0.5) / n;
      const double cy = -half + 2.0 * half * (j + 0.5) / n;
      if (std::abs(cx) < hole && std::abs(cy) < hole) continue;
      std::vector<std::uint32_t> quad{at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)};
      if (facing_down) std::swap(quad[1], quad[3]);
      for (const int k : {0, 1, 2, 0, 2, 3})
        s.indices.push_back(quad[static_cast<std::size_t>(k)]);
    }
  return s;
}

Aabb box(glm::dvec3 lo, glm::dvec3 hi) {
  Aabb b;
  b.extend(lo);
  b.extend(hi);
  return b;
}

/// The grid of a 256-pixel headset at the origin looking down -z, 64 cells across.
OccluderDepth with(const Surface& s, bool two_sided, const glm::dvec3& head = glm::dvec3(0.0)) {
  HeadPose pose = testing::at_origin();
  pose.position_mm = head;
  const auto eyes = eye_views(testing::square_headset(256), pose);
  OccluderDepth depth;
  depth.begin({eyes[0].view_projection, eyes[1].view_projection},
              {eyes[0].position_mm, eyes[1].position_mm}, 64, 64);
  const TriangleEdges edges = triangle_edges(s.indices, s.vertices.size() / 3);
  depth.add(s.vertices, 3, s.indices, edges, two_sided);
  return depth;
}

TEST(TriangleEdges, AClosedSolidHasEveryEdgeBetweenTwoTrianglesASheetItsRimAlone) {
  const Surface sphere = from_solid(testing::sphere_mm({0.0, 0.0, 0.0}, 10.0, 16));
  const TriangleEdges closed = triangle_edges(sphere.indices, sphere.vertices.size() / 3);
  EXPECT_EQ(closed.vertices.size() * 2, sphere.indices.size());  // E = 3T / 2
  for (const auto& t : closed.triangles)
    EXPECT_GE(t[1], 0);

  const Surface open = sheet(0.0, 10.0, 5);
  const TriangleEdges edges = triangle_edges(open.indices, open.vertices.size() / 3);
  std::size_t rim = 0;
  for (const auto& t : edges.triangles)
    rim += t[1] == TriangleEdges::kBoundary ? 1 : 0;
  EXPECT_EQ(rim, 4u * 5u);
  EXPECT_EQ(edges.vertices.size(), 5u * 5u * 3u + 2u * 5u);  // per quad 3, plus two sides
}

TEST(OccluderDepth, AFineSheetHidesWhatLiesWhollyBehindItAndNothingElse) {
  // 0.67 mm triangles, a fifth of a cell: no one triangle covers a cell, their union does.
  const OccluderDepth depth = with(sheet(-100.0, 40.0, 120), false);
  EXPECT_GT(depth.covered_cells(0), 400u);
  EXPECT_TRUE(depth.hides(box({-10.0, -10.0, -130.0}, {10.0, 10.0, -110.0})));
  EXPECT_FALSE(depth.hides(box({-10.0, -10.0, -90.0}, {10.0, 10.0, -80.0})))
      << "a box in front of the sheet";
  EXPECT_FALSE(depth.hides(box({-10.0, -10.0, -110.0}, {10.0, 10.0, -99.0})))
      << "a box through the sheet";
  EXPECT_FALSE(depth.hides(box({30.0, -5.0, -130.0}, {45.0, 5.0, -120.0})))
      << "a box behind the sheet's edge and past it";
  // Past the sheet's edge (y = 40 mm, 0.4 of the view) by less than half a cell, in the cell
  // whose centre the sheet covers: only the outline tells it is not covered whole.
  EXPECT_FALSE(depth.hides(box({-1.0, 79.5, -200.5}, {1.0, 80.5, -199.5})))
      << "a box peeking past the sheet's edge";
  EXPECT_FALSE(depth.hides(box({-10.0, -10.0, -100.05}, {10.0, 10.0, -100.01})))
      << "a box just behind the sheet, within the depth margin";
}

TEST(OccluderDepth, ABackFacingSheetHidesNothingUnlessDrawnTwoSided) {
  const Aabb behind = box({-10.0, -10.0, -130.0}, {10.0, 10.0, -110.0});
  const OccluderDepth culled = with(sheet(-100.0, 40.0, 40, true), false);
  EXPECT_EQ(culled.covered_cells(0), 0u);
  EXPECT_FALSE(culled.hides(behind));
  EXPECT_TRUE(with(sheet(-100.0, 40.0, 40, true), true).hides(behind));
}

TEST(OccluderDepth, AHoleInAnOpenSurfaceShowsWhatLiesBehindIt) {
  const OccluderDepth depth = with(sheet(-100.0, 40.0, 40, false, 10.0), true);
  EXPECT_FALSE(depth.hides(box({-3.0, -3.0, -130.0}, {3.0, 3.0, -120.0})));
  EXPECT_FALSE(depth.hides(box({5.0, -3.0, -130.0}, {15.0, 3.0, -120.0})))
      << "a box behind the hole's rim";
  // Beside the hole by more than two cells in both eyes.
  EXPECT_TRUE(depth.hides(box({-4.0, 20.0, -115.0}, {4.0, 28.0, -110.0})));
}

TEST(OccluderDepth, AClosedSolidHidesWhatItEnclosesNotWhatReachesOutOfIt) {
  const OccluderDepth depth = with(from_solid(testing::sphere_mm({0.0, 0.0, -150.0}, 30.0)), false);
  EXPECT_TRUE(depth.hides(box({-8.0, -8.0, -158.0}, {8.0, 8.0, -142.0})));
  EXPECT_TRUE(depth.hides(box({-8.0, -8.0, -200.0}, {8.0, 8.0, -185.0})))
      << "a box behind the solid";
  EXPECT_FALSE(depth.hides(box({-8.0, -8.0, -158.0}, {8.0, 8.0, -110.0})))
      << "a box through the near side";
  EXPECT_FALSE(depth.hides(box({24.0, -4.0, -200.0}, {40.0, 4.0, -185.0})))
      << "a box behind the solid's outline and past it";
}

TEST(OccluderDepth, AnEyeInsideASolidOrASurfaceReachingTheEyeHidesNothing) {
  const OccluderDepth inside = with(from_solid(testing::sphere_mm({0.0, 0.0, 0.0}, 30.0)), false);
  EXPECT_EQ(inside.covered_cells(0), 0u);
  EXPECT_FALSE(inside.hides(box({-5.0, -5.0, -60.0}, {5.0, 5.0, -50.0})));
  // A sheet whose far edge is 100 mm away and near edge behind the eye.
  Surface slanted = sheet(0.0, 60.0, 20);
  for (std::size_t v = 0; v < slanted.vertices.size(); v += 3) {
    const float y = slanted.vertices[v + 1];
    slanted.vertices[v + 1] = -40.0f;
    slanted.vertices[v + 2] = -40.0f + y;  // z from -100 to +20
  }
  const OccluderDepth reaching = with(slanted, true);
  EXPECT_EQ(reaching.covered_cells(0), 0u);
}

TEST(OccluderDepth, BothEyesMustBeHidden) {
  // A narrow post 80 mm away hides a small box 40 mm behind it from the left eye only when the
  // eyes are 64 mm apart: moved so that the left eye sees the box behind it, the right eye
  // looks past.
  const Surface post = from_solid(testing::sphere_mm({-32.0, 0.0, -80.0}, 6.0));
  const OccluderDepth depth = with(post, false);
  const Aabb behind_left = box({-33.0, -1.0, -121.0}, {-31.0, 1.0, -119.0});
  EXPECT_FALSE(depth.hides(behind_left));
  const OccluderDepth wide = with(from_solid(testing::sphere_mm({0.0, 0.0, -80.0}, 40.0)), false);
  EXPECT_TRUE(wide.hides(box({-1.0, -1.0, -161.0}, {1.0, 1.0, -159.0})));
}

}  // namespace
}  // namespace bisturi::render
