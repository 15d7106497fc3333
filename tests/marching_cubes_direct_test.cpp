// extract_isosurface writes the DLFL straight from the cell tables. It must give the
// structure build_oriented_manifold makes from the same triangles: the same vertices in the same
// order, triangle t as face t with the same corner cycle, the same edges, rotations and labelled
// border loops, and a valid closed or bordered oriented 2-manifold.

#include <gtest/gtest.h>

#include <random>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/bono_octree.h"
#include "bisturi/scene/volume/marching_cubes.h"

namespace bisturi {
namespace {

std::size_t bounding_faces(const Dlfl& d) {
  std::size_t n = 0;
  for (std::uint32_t f = 0; f < d.face_capacity(); ++f)
    n += d.alive(FaceId(f)) && d.is_bounding(FaceId(f)) ? 1 : 0;
  return n;
}

void expect_same_as_builder(const Grid<float>& g, const IsoSurfaceOptions& options,
                            const std::string& what) {
  const PolygonMesh tri = extract_isosurface_mesh(g, options);
  const Dlfl reference = build_oriented_manifold(tri);
  ExtractionStats stats;
  const Dlfl direct = extract_isosurface(g, options, &stats);
  const ValidationReport report = validate(direct);
  ASSERT_TRUE(report.ok()) << what << ": " << report.summary();
  ASSERT_EQ(direct.num_vertices(), reference.num_vertices()) << what;
  ASSERT_EQ(direct.num_faces(), reference.num_faces()) << what;
  ASSERT_EQ(direct.num_edges(), reference.num_edges()) << what;
  ASSERT_EQ(direct.num_corners(), reference.num_corners()) << what;
  ASSERT_EQ(direct.num_rotations(), reference.num_rotations()) << what;
  ASSERT_EQ(bounding_faces(direct), bounding_faces(reference)) << what;
  EXPECT_EQ(stats.triangles, tri.face_count()) << what;
  EXPECT_EQ(stats.vertices, tri.positions.size()) << what;
  for (std::uint32_t v = 0; v < direct.num_vertices(); ++v) {
    ASSERT_EQ(direct.position(VertexId(v)), tri.positions[v]) << what << " vertex " << v;
  }
  for (std::uint32_t t = 0; t < tri.face_count(); ++t) {
    const auto face = tri.face(t);
    CornerId c = direct.first_corner(FaceId(t));
    for (std::uint32_t k = 0; k < 3; ++k, c = direct.next(c)) {
      ASSERT_EQ(direct.vertex(c).idx, face[k]) << what << " triangle " << t;
      ASSERT_EQ(direct.vertex(direct.next(c)).idx, face[(k + 1) % 3]) << what;
      // The twin side runs back.
      const CornerId twin = direct.partner(c);
      ASSERT_EQ(direct.vertex(twin).idx, face[(k + 1) % 3]) << what;
      ASSERT_EQ(direct.vertex(direct.next(twin)).idx, face[k]) << what;
    }
    ASSERT_EQ(c, direct.first_corner(FaceId(t))) << what;
  }
}

TEST(MarchingCubesDirect, RandomVolumesMatchTheBuilder) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<float> real(-1.0f, 1.0f);
  std::uniform_int_distribution<int> level(-2, 2);
  for (int seed = 0; seed < 400; ++seed) {
    Grid<float> g;
    const std::int64_t side = 2 + seed % 7;
    g.geometry.dims = {side + seed % 3, side, side + 1 - seed % 2};
    g.geometry.spacing = glm::dvec3(0.5, 0.4, 0.6);
    if (seed % 4 == 1) g.geometry.direction[2] = -g.geometry.direction[2];  // mirrored
    g.values.resize(g.geometry.voxel_count());
    for (float& v : g.values)
      v = seed % 2 == 0 ? real(rng) : float(level(rng));
    IsoSurfaceOptions options;
    options.iso = seed % 2 == 0 ? real(rng) * 0.5f : 0.0f;
    if (seed % 5 == 2) options.placement = VertexPlacement::Cubic;
    expect_same_as_builder(g, options, "seed " + std::to_string(seed));
    if (seed % 3 == 0) {
      options.build_octree = true;
      expect_same_as_builder(g, options, "octree seed " + std::to_string(seed));
    }
  }
}

TEST(MarchingCubesDirect, LargerBlobsAndTubes) {
  // Smooth random fields on 40^3: many parts, holes through the border, some with tunnels.
  std::mt19937_64 rng(3);
  std::uniform_real_distribution<double> real(-1.0, 1.0);
  for (int seed = 0; seed < 6; ++seed) {
    Grid<float> g;
    g.geometry.dims = {40, 37, 33};
    g.geometry.spacing = glm::dvec3(0.5);
    g.values.resize(g.geometry.voxel_count());
    std::array<double, 9> c{};
    for (double& x : c)
      x = real(rng);
    std::size_t idx = 0;
    for (std::int64_t k = 0; k < 33; ++k) {
      for (std::int64_t j = 0; j < 37; ++j) {
        for (std::int64_t i = 0; i < 40; ++i, ++idx) {
          const double x = 0.3 * double(i) + c[0], y = 0.27 * double(j) + c[1],
                       z = 0.33 * double(k) + c[2];
          g.values[idx] = static_cast<float>(std::sin(x) * std::cos(y) + std::sin(y) * std::cos(z) +
                                             std::sin(z) * std::cos(x) + 0.3 * c[3]);
        }
      }
    }
    IsoSurfaceOptions options;
    expect_same_as_builder(g, options, "gyroid seed " + std::to_string(seed));
  }
}

TEST(MarchingCubesDirect, BuildProgressReachesTheEdgeCount) {
  Grid<float> g;
  g.geometry.dims = {20, 20, 20};
  g.values.resize(g.geometry.voxel_count());
  std::size_t idx = 0;
  for (std::int64_t k = 0; k < 20; ++k)
    for (std::int64_t j = 0; j < 20; ++j)
      for (std::int64_t i = 0; i < 20; ++i, ++idx)
        g.values[idx] = float(
            7.0 - std::sqrt(double((i - 9) * (i - 9) + (j - 10) * (j - 10) + (k - 9) * (k - 9))));
  IsoSurfaceOptions options;
  std::size_t last = 0, total = 0;
  options.build_progress = [&](std::size_t done, std::size_t all) {
    EXPECT_GE(done, last);
    last = done;
    total = all;
  };
  const Dlfl d = extract_isosurface(g, options);
  EXPECT_EQ(last, total);
  EXPECT_EQ(total, d.num_edges());
}

}  // namespace
}  // namespace bisturi
