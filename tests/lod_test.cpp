// Levels of detail: QEM decimation keeps topology (genus, parts, boundary loops and their
// vertices) and stays close to the surface; Taubin smoothing removes noise without shrinking;
// subdivision levels refine once and re-interpolate to exactly what a fresh build gives.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <numbers>
#include <random>
#include <vector>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/lod/subdivision.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/shapes.h"

namespace bisturi {
namespace {

using Vec3 = Dlfl::Vec3;

/// Latitude-longitude sphere of triangles with a vertex at each pole (closed, genus 0).
PolygonMesh uv_sphere(std::size_t n_lat, std::size_t n_lon, double radius) {
  PolygonMesh m;
  m.positions.emplace_back(0.0, 0.0, -radius);
  for (std::size_t i = 1; i < n_lat; ++i) {
    const double theta = std::numbers::pi * double(i) / double(n_lat) - std::numbers::pi / 2;
    for (std::size_t j = 0; j < n_lon; ++j) {
      const double phi = 2.0 * std::numbers::pi * double(j) / double(n_lon);
      m.positions.emplace_back(radius * std::cos(theta) * std::cos(phi),
                               radius * std::cos(theta) * std::sin(phi), radius * std::sin(theta));
    }
  }
  m.positions.emplace_back(0.0, 0.0, radius);
  const auto ring = [n_lon](std::size_t i, std::size_t j) {
    return static_cast<std::uint32_t>(1 + (i - 1) * n_lon + j % n_lon);
  };
  const auto top = static_cast<std::uint32_t>(m.positions.size() - 1);
  for (std::size_t j = 0; j < n_lon; ++j) {
    m.add_face({0, ring(1, j + 1), ring(1, j)});
    m.add_face({top, ring(n_lat - 1, j), ring(n_lat - 1, j + 1)});
  }
  for (std::size_t i = 1; i + 1 < n_lat; ++i) {
    for (std::size_t j = 0; j < n_lon; ++j) {
      m.add_face({ring(i, j), ring(i, j + 1), ring(i + 1, j + 1)});
      m.add_face({ring(i, j), ring(i + 1, j + 1), ring(i + 1, j)});
    }
  }
  return m;
}

/// Icosahedron whose triangles are split into four `splits` times, projected to the sphere
/// (20 * 4^splits triangles, valences 5 and 6).
PolygonMesh icosphere(double radius, int splits) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  std::vector<Vec3> v = {{-1, t, 0},  {1, t, 0},  {-1, -t, 0}, {1, -t, 0}, {0, -1, t},  {0, 1, t},
                         {0, -1, -t}, {0, 1, -t}, {t, 0, -1},  {t, 0, 1},  {-t, 0, -1}, {-t, 0, 1}};
  std::vector<std::array<std::uint32_t, 3>> tris = {
      {0, 11, 5},  {0, 5, 1},  {0, 1, 7},  {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},   {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (Vec3& p : v)
    p = radius * glm::normalize(p);
  for (int s = 0; s < splits; ++s) {
    std::map<std::pair<std::uint32_t, std::uint32_t>, std::uint32_t> mid;
    auto midpoint = [&](std::uint32_t a, std::uint32_t b) {
      auto [it, fresh] = mid.try_emplace(std::minmax(a, b), static_cast<std::uint32_t>(v.size()));
      if (fresh) v.push_back(radius * glm::normalize(v[a] + v[b]));
      return it->second;
    };
    std::vector<std::array<std::uint32_t, 3>> finer;
    for (const auto& f : tris) {
      const std::uint32_t ab = midpoint(f[0], f[1]), bc = midpoint(f[1], f[2]);
      const std::uint32_t ca = midpoint(f[2], f[0]);
      finer.push_back({f[0], ab, ca});
      finer.push_back({f[1], bc, ab});
      finer.push_back({f[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    tris = std::move(finer);
  }
  PolygonMesh m;
  m.positions.assign(v.begin(), v.end());
  for (const auto& f : tris)
    m.add_face({f[0], f[1], f[2]});
  return m;
}

/// Every polygon split into a fan of triangles.
PolygonMesh triangulated(const PolygonMesh& in) {
  PolygonMesh out;
  out.positions = in.positions;
  for (std::size_t f = 0; f < in.face_count(); ++f) {
    const auto face = in.face(f);
    for (std::size_t i = 1; i + 1 < face.size(); ++i)
      out.add_face({face[0], face[i], face[i + 1]});
  }
  return out;
}

lod::DecimateOptions to_faces(std::size_t n) {
  lod::DecimateOptions o;
  o.target_faces = n;
  return o;
}

lod::SubdivisionOptions sub(int levels,
                            lod::SubdivisionScheme scheme = lod::SubdivisionScheme::Automatic) {
  lod::SubdivisionOptions o;
  o.levels = levels;
  o.scheme = scheme;
  return o;
}

double torus_distance(const Vec3& p, double major, double minor) {
  const double rho = std::sqrt(p.x * p.x + p.y * p.y) - major;
  return std::abs(std::sqrt(rho * rho + p.z * p.z) - minor);
}

void expect_valid(const Dlfl& d) {
  const auto report = validate(d);
  EXPECT_TRUE(report.ok()) << report.summary();
}

bool all_triangles(const Dlfl& d) {
  const auto polys = export_polygons(d).polygons;
  for (std::size_t f = 0; f < polys.face_count(); ++f) {
    if (polys.face(f).size() != 3) return false;
  }
  return true;
}

// ------------------------------------------------------------------------------ decimation

TEST(Decimate, TorusToTenPercentKeepsGenusAndShape) {
  const double R = 1.0, r = 0.35;
  Dlfl d = build_oriented_manifold(torus_mesh(R, r, 200, 100, true));
  ASSERT_EQ(lod::polygon_face_count(d), 40000u);
  lod::DecimateOptions opt;
  opt.target_faces = 4000;
  std::size_t calls = 0, last_done = 0;
  bool monotonic = true;
  opt.progress = [&](std::size_t done, std::size_t total) {
    ++calls;
    monotonic = monotonic && done >= last_done && total == 18000u;
    last_done = done;
  };
  const auto t0 = std::chrono::steady_clock::now();
  const auto stats = lod::decimate(d, opt);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  EXPECT_TRUE(stats.reached_target);
  EXPECT_EQ(stats.initial_faces, 40000u);
  EXPECT_EQ(stats.final_faces, 4000u);
  EXPECT_EQ(stats.collapses, 18000u);
  EXPECT_EQ(lod::polygon_face_count(d), 4000u);
  EXPECT_GT(calls, 50u);
  EXPECT_TRUE(monotonic);
  EXPECT_EQ(last_done, 18000u);
  expect_valid(d);
  EXPECT_TRUE(all_triangles(d));
  const auto s = mesh_statistics(d);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].genus, 1);
  EXPECT_EQ(s.bounding_faces, 0u);
  EXPECT_EQ(s.vertices, 2000u);
  // Vertices and face centroids stay near the analytic torus.
  double max_vertex = 0.0, max_centroid = 0.0;
  const auto polys = export_polygons(d).polygons;
  for (const Vec3& p : polys.positions)
    max_vertex = std::max(max_vertex, torus_distance(p, R, r));
  for (std::size_t f = 0; f < polys.face_count(); ++f) {
    Vec3 c(0.0);
    for (const auto i : polys.face(f))
      c += polys.positions[i];
    max_centroid = std::max(max_centroid, torus_distance(c / 3.0, R, r));
  }
  std::printf(
      "torus 40000 -> %zu faces in %.1f ms: %zu collapses, %zu/%zu refused "
      "(topology/geometry), quadric error %.2e, max distance vertex %.2e centroid %.2e\n",
      stats.final_faces, ms, stats.collapses, stats.rejected_topology, stats.rejected_geometry,
      stats.max_error, max_vertex, max_centroid);
  EXPECT_LT(max_vertex, 0.01 * r);
  EXPECT_LT(max_centroid, 0.02 * r);
  d.compact();
  expect_valid(d);
}

TEST(Decimate, SphereKeepsGenusZero) {
  Dlfl d = build_oriented_manifold(uv_sphere(60, 120, 1.0));
  lod::DecimateOptions opt;
  opt.target_faces = 300;
  const auto stats = lod::decimate(d, opt);
  EXPECT_EQ(stats.final_faces, 300u);
  expect_valid(d);
  EXPECT_TRUE(all_triangles(d));
  const auto s = mesh_statistics(d);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].genus, 0);
  for (const Vec3& p : export_polygons(d).polygons.positions)
    EXPECT_NEAR(glm::length(p), 1.0, 0.02);
}

TEST(Decimate, DecimatingAsFarAsPossibleKeepsTopology) {
  // No target, no error bound: collapse until the link condition refuses everything.
  Dlfl sphere = build_oriented_manifold(uv_sphere(20, 40, 1.0));
  const auto a = lod::decimate(sphere);
  expect_valid(sphere);
  const auto sa = mesh_statistics(sphere);
  ASSERT_EQ(sa.parts.size(), 1u);
  EXPECT_EQ(sa.parts[0].genus, 0);
  EXPECT_LE(a.final_faces, 12u);  // close to the tetrahedron
  EXPECT_GE(a.final_faces, 4u);

  Dlfl torus = build_oriented_manifold(torus_mesh(1.0, 0.4, 40, 20, true));
  lod::DecimateOptions opt;
  opt.min_normal_cosine = -1.0;  // geometry may fold: only topology limits the collapses
  const auto b = lod::decimate(torus, opt);
  expect_valid(torus);
  const auto sb = mesh_statistics(torus);
  ASSERT_EQ(sb.parts.size(), 1u);
  EXPECT_EQ(sb.parts[0].genus, 1);
  EXPECT_GT(b.rejected_topology, 0u);
  EXPECT_LT(b.final_faces, 100u);
}

TEST(Decimate, OpenTubeKeepsBoundaryLoopsAndVertices) {
  Dlfl d = build_oriented_manifold(triangulated(tube_mesh(1.0, 4.0, 64, 60)));
  ASSERT_EQ(boundary_loops(d).size(), 2u);
  // The boundary vertices and their positions, by handle.
  std::map<std::uint32_t, Vec3> boundary;
  for (const FaceId loop : boundary_loops(d)) {
    for (const VertexId v : face_vertices(d, loop))
      boundary[v.idx] = d.position(v);
  }
  ASSERT_EQ(boundary.size(), 128u);
  const std::size_t before = lod::polygon_face_count(d);
  lod::DecimateOptions opt;
  opt.target_faces = before / 10;
  const auto stats = lod::decimate(d, opt);
  EXPECT_EQ(stats.fixed_vertices, 128u);
  EXPECT_LE(stats.final_faces, before / 10 + 1);
  expect_valid(d);
  EXPECT_TRUE(all_triangles(d));
  const auto loops = boundary_loops(d);
  ASSERT_EQ(loops.size(), 2u);
  std::size_t seen = 0;
  for (const FaceId loop : loops) {
    const auto vs = face_vertices(d, loop);
    EXPECT_EQ(vs.size(), 64u);
    for (const VertexId v : vs) {
      auto it = boundary.find(v.idx);
      ASSERT_NE(it, boundary.end());
      EXPECT_EQ(d.position(v), it->second);
      ++seen;
    }
  }
  EXPECT_EQ(seen, 128u);
  const auto s = mesh_statistics(d);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].genus, 0);
  EXPECT_EQ(s.parts[0].rings, 2u);
  for (const Vec3& p : export_polygons(d).polygons.positions)
    EXPECT_NEAR(std::hypot(p.x, p.y), 1.0, 0.02);
}

/// The thinnest triangle of a mesh (4 sqrt(3) area over the squared edges' sum) and its longest
/// edge.
struct TriangleShapes {
  double thinnest = 1.0, longest_edge = 0.0;
};
TriangleShapes triangle_shapes(const Dlfl& d) {
  const PolygonMesh m = export_polygons(d).polygons;
  TriangleShapes s;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const auto c = m.face(f);
    if (c.size() != 3) continue;
    const Vec3 a = m.positions[c[0]], b = m.positions[c[1]], e = m.positions[c[2]];
    const double edges = glm::dot(b - a, b - a) + glm::dot(e - b, e - b) + glm::dot(a - e, a - e);
    s.thinnest =
        std::min(s.thinnest, 2.0 * std::sqrt(3.0) * glm::length(glm::cross(b - a, e - a)) / edges);
    s.longest_edge =
        std::max({s.longest_edge, glm::length(b - a), glm::length(e - b), glm::length(a - e)});
  }
  return s;
}

// A vessel's tube, 12 mm across and 60 mm long, decimated to a quarter: the quadrics alone are
// zero along a straight tube and thin it to slivers most of its length long; with a quality
// bound no face is thinner than the bound (the tube starts with none) and the tube keeps rings
// along its length, as a simulated vessel needs to bend.
TEST(Decimate, AQualityBoundKeepsATubeFromThinningToSlivers) {
  const PolygonMesh tube = triangulated(tube_mesh(6.0, 60.0, 32, 30));
  Dlfl plain = build_oriented_manifold(tube);
  Dlfl bounded = build_oriented_manifold(tube);
  ASSERT_GT(triangle_shapes(plain).thinnest, 0.3);
  lod::DecimateOptions opt;
  opt.target_faces = lod::polygon_face_count(plain) / 4;
  (void)lod::decimate(plain, opt);
  opt.min_triangle_quality = 0.3;
  const auto stats = lod::decimate(bounded, opt);
  EXPECT_TRUE(stats.reached_target);
  expect_valid(bounded);
  const TriangleShapes p = triangle_shapes(plain), b = triangle_shapes(bounded);
  EXPECT_LT(p.thinnest, 0.1) << "without the bound: slivers";
  EXPECT_GT(p.longest_edge, 30.0);
  EXPECT_GE(b.thinnest, 0.3);
  EXPECT_LT(b.longest_edge, 15.0);
}

TEST(Decimate, StopsAtTheErrorBound) {
  Dlfl d = build_oriented_manifold(torus_mesh(1.0, 0.35, 120, 60, true));
  lod::DecimateOptions opt;
  opt.max_error = 1e-3;
  const auto stats = lod::decimate(d, opt);
  EXPECT_TRUE(stats.stopped_by_error);
  EXPECT_FALSE(stats.reached_target);
  EXPECT_LE(stats.max_error, 1e-3);
  EXPECT_GT(stats.collapses, 300u);
  EXPECT_LT(stats.final_faces, stats.initial_faces);
  double max_vertex = 0.0;
  for (const Vec3& p : export_polygons(d).polygons.positions)
    max_vertex = std::max(max_vertex, torus_distance(p, 1.0, 0.35));
  EXPECT_LE(max_vertex, 1e-3);
  expect_valid(d);
  EXPECT_EQ(mesh_statistics(d).parts.at(0).genus, 1);

  // Both bounds: the face target comes first with a loose error bound...
  Dlfl e = build_oriented_manifold(torus_mesh(1.0, 0.35, 120, 60, true));
  opt.max_error = 1.0;
  opt.target_faces = 10000;
  EXPECT_TRUE(lod::decimate(e, opt).reached_target);
  // ...and the error bound with a tight one.
  Dlfl f = build_oriented_manifold(torus_mesh(1.0, 0.35, 120, 60, true));
  opt.max_error = 1e-5;
  const auto tight = lod::decimate(f, opt);
  EXPECT_TRUE(tight.stopped_by_error);
  EXPECT_GT(tight.final_faces, 10000u);
}

TEST(Decimate, FlatRegionsGoFirstAndExactly) {
  // A flat triangulated grid: every interior collapse costs nothing; boundary stays.
  Dlfl d = build_oriented_manifold(grid_mesh(20, 20, 0.1, true));
  lod::DecimateOptions opt;
  opt.max_error = 1e-12;
  const auto stats = lod::decimate(d, opt);
  expect_valid(d);
  EXPECT_EQ(stats.fixed_vertices, 80u);
  EXPECT_EQ(boundary_loops(d).size(), 1u);
  for (const Vec3& p : export_polygons(d).polygons.positions)
    EXPECT_EQ(p.z, 0.0);
  // A disc with 80 boundary vertices and Vi interior ones has 78 + 2 Vi triangles; of the 361
  // interior vertices only a few stay (where a collapse onto a straight side would leave a
  // degenerate triangle).
  std::printf("flat grid: 800 -> %zu faces\n", stats.final_faces);
  EXPECT_GE(stats.final_faces, 78u);
  EXPECT_LE(stats.final_faces, 90u);
}

TEST(Decimate, TetrahedronIsLeftAlone) {
  Dlfl d = build_oriented_manifold(tetrahedron_mesh());
  lod::DecimateOptions opt;
  opt.target_faces = 2;
  const auto stats = lod::decimate(d, opt);
  EXPECT_EQ(stats.collapses, 0u);
  EXPECT_EQ(stats.final_faces, 4u);
  EXPECT_FALSE(stats.reached_target);
  EXPECT_GT(stats.rejected_topology, 0u);
  expect_valid(d);
  EXPECT_EQ(d.num_vertices(), 4u);
  EXPECT_EQ(mesh_statistics(d).parts.at(0).genus, 0);
}

TEST(Decimate, QuadMeshVerticesStayFixed) {
  // Vertices of non-triangular faces are never removed: a quad torus is left as it is.
  Dlfl d = build_oriented_manifold(torus_mesh(1.0, 0.3, 12, 8, false));
  const auto stats = lod::decimate(d, to_faces(10));
  EXPECT_EQ(stats.collapses, 0u);
  EXPECT_EQ(stats.fixed_vertices, 96u);
  expect_valid(d);
}

// ------------------------------------------------------------------------------- smoothing

TEST(Smooth, TaubinRemovesNoiseWithoutShrinking) {
  PolygonMesh m = icosphere(1.0, 5);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> noise(-0.02, 0.02);
  for (auto& p : m.positions)
    p *= 1.0 + noise(rng);
  Dlfl d = build_oriented_manifold(m);
  auto roughness = [&](double& mean) {
    double sum = 0.0, sum2 = 0.0;
    const auto& pos = d.positions();
    for (const auto& p : pos)
      sum += glm::length(p);
    mean = sum / double(pos.size());
    for (const auto& p : pos)
      sum2 += (glm::length(p) - mean) * (glm::length(p) - mean);
    return std::sqrt(sum2 / double(pos.size()));
  };
  double mean_before = 0.0, mean_after = 0.0;
  const double rough_before = roughness(mean_before);
  std::size_t progress_calls = 0;
  lod::SmoothOptions opt;
  opt.iterations = 10;
  opt.progress = [&](std::size_t, std::size_t total) {
    ++progress_calls;
    EXPECT_EQ(total, 10u);
  };
  const auto stats = lod::smooth_taubin(d, opt);
  const double rough_after = roughness(mean_after);
  std::printf("Taubin x10: radius spread %.4f -> %.4f, mean radius %.5f -> %.5f\n", rough_before,
              rough_after, mean_before, mean_after);
  EXPECT_EQ(progress_calls, 10u);
  EXPECT_EQ(stats.fixed_vertices, 0u);
  // White noise also has components below the pass band (k_pb = 0.1), which Taubin keeps.
  EXPECT_LT(rough_after, 0.45 * rough_before);
  EXPECT_NEAR(mean_after, mean_before, 0.01 * mean_before);
  expect_valid(d);

  // Plain Laplacian smoothing (mu = 0 is refused: Taubin needs mu < -lambda).
  opt.mu = 0.0;
  EXPECT_THROW(lod::smooth_taubin(d, opt), InputError);
}

TEST(Smooth, BoundaryVerticesStayFixed) {
  PolygonMesh m = grid_mesh(20, 20, 0.1, true);
  std::mt19937 rng(3);
  std::uniform_real_distribution<double> noise(-0.01, 0.01);
  for (auto& p : m.positions)
    p.z = noise(rng);
  Dlfl d = build_oriented_manifold(m);
  std::map<std::uint32_t, Vec3> boundary;
  for (const VertexId v : face_vertices(d, boundary_loops(d).at(0)))
    boundary[v.idx] = d.position(v);
  lod::SmoothOptions opt;
  opt.iterations = 20;
  const auto stats = lod::smooth_taubin(d, opt);
  EXPECT_EQ(stats.fixed_vertices, 80u);
  EXPECT_EQ(stats.moved_vertices, 19u * 19u);
  for (const auto& [v, p] : boundary)
    EXPECT_EQ(d.position(VertexId(v)), p);
  double max_z = 0.0;
  for (std::uint32_t v = 0; v < d.vertex_capacity(); ++v) {
    if (!boundary.contains(v)) max_z = std::max(max_z, std::abs(d.position(VertexId(v)).z));
  }
  EXPECT_LT(max_z, 0.006);
}

// ----------------------------------------------------------------------------- subdivision

TEST(Subdivision, FaceCountsPerLevel) {
  const Dlfl cube = build_oriented_manifold(cube_mesh({0, 0, 0}, 1.0));
  const lod::SubdivisionLevels cc(cube, sub(3));
  EXPECT_EQ(cc.scheme(), lod::SubdivisionScheme::CatmullClark);
  EXPECT_EQ(cc.face_count(0), 6u);
  EXPECT_EQ(cc.face_count(1), 24u);
  EXPECT_EQ(cc.face_count(2), 96u);
  EXPECT_EQ(cc.face_count(3), 384u);
  EXPECT_EQ(cc.vertex_count(1), 26u);
  EXPECT_EQ(cc.vertex_count(2), 98u);
  const auto l3 = cc.level_mesh(3);
  for (std::size_t f = 0; f < l3.face_count(); ++f)
    EXPECT_EQ(l3.face(f).size(), 4u);

  const Dlfl torus = build_oriented_manifold(torus_mesh(1.0, 0.3, 24, 12, true));
  const lod::SubdivisionLevels loop(torus, sub(2));
  EXPECT_EQ(loop.scheme(), lod::SubdivisionScheme::Loop);
  EXPECT_EQ(loop.face_count(1), 4u * 576u);
  EXPECT_EQ(loop.face_count(2), 16u * 576u);
  // Catmull-Clark on triangles: each triangle gives three quads, then x4.
  const lod::SubdivisionLevels cct(torus, sub(2, lod::SubdivisionScheme::CatmullClark));
  EXPECT_EQ(cct.face_count(1), 3u * 576u);
  EXPECT_EQ(cct.face_count(2), 12u * 576u);
  // Loop on quads is refused; levels are checked.
  EXPECT_THROW(lod::SubdivisionLevels(cube, sub(2, lod::SubdivisionScheme::Loop)), InputError);
  EXPECT_THROW(lod::SubdivisionLevels(cube, sub(9)), InputError);
  EXPECT_THROW((void)cc.positions(4), InputError);
}

TEST(Subdivision, SphereControlMeshConvergesToASphere) {
  // The refined points of an icosphere converge to the Loop limit surface, which is close to a
  // (slightly smaller) sphere: the mean radius settles geometrically and the spread stays small.
  const Dlfl control = build_oriented_manifold(icosphere(1.0, 1));
  const lod::SubdivisionLevels levels(control, sub(5));
  std::vector<double> mean(6), spread(6);
  for (int l = 0; l <= 5; ++l) {
    double lo = 1e9, hi = 0.0, sum = 0.0;
    for (const Vec3& p : levels.positions(l)) {
      lo = std::min(lo, glm::length(p));
      hi = std::max(hi, glm::length(p));
      sum += glm::length(p);
    }
    const auto i = static_cast<std::size_t>(l);
    mean[i] = sum / double(levels.vertex_count(l));
    spread[i] = (hi - lo) / mean[i];
    std::printf("Loop level %d: %zu faces, radius %.5f .. %.5f (mean %.5f)\n", l,
                levels.face_count(l), lo, hi, mean[i]);
  }
  for (std::size_t l = 2; l <= 5; ++l) {
    EXPECT_LT(std::abs(mean[l] - mean[l - 1]), 0.5 * std::abs(mean[l - 1] - mean[l - 2]));
  }
  EXPECT_LT(spread[5], 0.015);
  EXPECT_GT(mean[5], 0.9);
}

TEST(Subdivision, UpdateEqualsAFreshBuild) {
  const PolygonMesh base = torus_mesh(1.0, 0.3, 30, 16, false);
  Dlfl control = build_oriented_manifold(base);
  lod::SubdivisionLevels levels(control, sub(2));
  // Move the control vertices (a bend and some noise) and re-interpolate only.
  std::mt19937 rng(11);
  std::uniform_real_distribution<double> noise(-0.05, 0.05);
  PolygonMesh moved = base;
  for (std::uint32_t i = 0; i < moved.positions.size(); ++i) {
    Vec3& p = moved.positions[i];
    p += Vec3(noise(rng), noise(rng), 0.3 * p.x * p.x + noise(rng));
  }
  const auto& cv = levels.control_vertices();
  ASSERT_EQ(cv.size(), moved.positions.size());
  for (std::size_t i = 0; i < cv.size(); ++i)
    control.set_position(cv[i], moved.positions[cv[i].idx]);
  levels.update(control);
  const lod::SubdivisionLevels fresh(build_oriented_manifold(moved), sub(2));
  for (int l = 0; l <= 2; ++l) {
    const auto a = levels.positions(l);
    const auto b = fresh.positions(l);
    ASSERT_EQ(a.size(), b.size());
    double worst = 0.0;
    for (std::size_t i = 0; i < a.size(); ++i)
      worst = std::max(worst, glm::length(a[i] - b[i]));
    EXPECT_LE(worst, 1e-12) << "level " << l;
  }
  // The span overload gives the same, and a topology change is caught.
  std::vector<Vec3> in_order;
  for (const VertexId v : cv)
    in_order.push_back(control.position(v));
  levels.update(in_order);
  EXPECT_EQ(levels.positions(2)[17], fresh.positions(2)[17]);
  EXPECT_THROW(levels.update(std::span<const Vec3>(in_order.data(), 3)), InputError);
  control.delete_edge(control.edge(control.first_corner(FaceId(0))));
  EXPECT_THROW(levels.update(control), TopologyError);
}

TEST(Subdivision, LevelDlflKeepsTopology) {
  const Dlfl torus = build_oriented_manifold(torus_mesh(1.0, 0.3, 16, 8, true));
  const lod::SubdivisionLevels t(torus, sub(2));
  const Dlfl t2 = t.build_level(2);
  expect_valid(t2);
  auto s = mesh_statistics(t2);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].genus, 1);
  EXPECT_EQ(lod::polygon_face_count(t2), 16u * 256u);

  // An open tube: boundaries pass through, two loops on every level.
  const Dlfl tube = build_oriented_manifold(tube_mesh(1.0, 2.0, 12, 6));
  const lod::SubdivisionLevels u(tube, sub(2));
  const Dlfl u2 = u.build_level(2);
  expect_valid(u2);
  s = mesh_statistics(u2);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].rings, 2u);
  EXPECT_EQ(s.parts[0].genus, 0);
  // Boundary edges are creases: boundary points stay on the end circles.
  for (const FaceId loop : boundary_loops(u2)) {
    for (const VertexId v : face_vertices(u2, loop)) {
      const Vec3 p = u2.position(v);
      EXPECT_TRUE(std::abs(p.z) < 1e-12 || std::abs(p.z - 2.0) < 1e-12);
    }
  }
  // The control mesh can be decimated first: decimation and subdivision compose.
  Dlfl fine = build_oriented_manifold(torus_mesh(1.0, 0.3, 60, 30, true));
  lod::decimate(fine, to_faces(400));
  fine.compact();
  const lod::SubdivisionLevels back(fine, sub(2));
  const Dlfl b2 = back.build_level(2);
  expect_valid(b2);
  EXPECT_EQ(mesh_statistics(b2).parts.at(0).genus, 1);
  EXPECT_EQ(lod::polygon_face_count(b2), 6400u);
}

TEST(Subdivision, NonManifoldVertexPassesThrough) {
  // Two tetrahedra sharing one vertex: a non-manifold junction in the control mesh.
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {-1, 0, 0}, {0, -1, 0}, {0, 0, -1}};
  m.add_face({0, 2, 1});
  m.add_face({0, 1, 3});
  m.add_face({1, 2, 3});
  m.add_face({0, 3, 2});
  m.add_face({0, 5, 4});
  m.add_face({0, 4, 6});
  m.add_face({4, 5, 6});
  m.add_face({0, 6, 5});
  const Dlfl d = import_polygons(m, true).mesh;
  ASSERT_EQ(non_manifold_vertices(d).size(), 1u);
  const lod::SubdivisionLevels levels(d, sub(2));
  EXPECT_EQ(levels.face_count(2), 8u * 16u);
  const Dlfl l2 = levels.build_level(2);
  expect_valid(l2);
  EXPECT_EQ(non_manifold_vertices(l2).size(), 1u);
  EXPECT_EQ(mesh_statistics(l2).parts.size(), 2u);
  // Decimation leaves the junction where it is.
  Dlfl l2d = levels.build_level(2);
  const auto junction = non_manifold_vertices(l2d).at(0);
  const Vec3 at = l2d.position(junction);
  const auto stats = lod::decimate(l2d, to_faces(40));
  expect_valid(l2d);
  EXPECT_TRUE(l2d.alive(junction));
  EXPECT_EQ(l2d.position(junction), at);
  EXPECT_GE(stats.fixed_vertices, 1u);
  EXPECT_EQ(mesh_statistics(l2d).parts.size(), 2u);
}

}  // namespace
}  // namespace bisturi
