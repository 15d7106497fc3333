// Cutting: across a square sheet gives exactly two parts, inside it one new boundary loop, a
// diagonal cut splits faces with insert_edge; validate() passes after every cut; springs,
// masses and the BVH follow; a cut that opens nothing is refused without a change.

#include <gtest/gtest.h>

#include <cmath>

#include <glm/geometric.hpp>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/errors.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

SoftBody square() {
  return SoftBody(testing::sheet(10, 10, 10.0), Material{});
}

TEST(SimCutting, CutAcrossSquareSheetGivesTwoParts) {
  SoftBody body = square();
  const std::vector<glm::dvec3> blade{{-0.005, 0.05, 0.0}, {0.105, 0.05, 0.0}};
  const CutResult r = cut_surface(body, blade);
  const ValidationReport report = validate(body.mesh());
  ASSERT_TRUE(report.ok()) << report.summary();
  EXPECT_TRUE(r.starts_on_boundary);
  EXPECT_TRUE(r.ends_on_boundary);
  EXPECT_EQ(r.path.size(), 11u);
  EXPECT_EQ(r.new_vertices.size(), 11u);
  const auto parts = connected_parts(body.mesh());
  EXPECT_EQ(parts.size(), 2u);
  EXPECT_EQ(boundary_loops(body.mesh()).size(), 2u);
  for (const Part& part : parts)
    EXPECT_EQ(part_topology(body.mesh(), part).genus, 0);
  double total_mass = 0.0;
  for (double m : body.masses())
    total_mass += m;
  const Material mat;
  EXPECT_NEAR(total_mass, mat.density_kg_per_m3 * mat.thickness_m * 0.01, 1e-12);
}

TEST(SimCutting, CutInsideSheetOpensOneNewBoundaryLoop) {
  SoftBody body = square();
  ASSERT_EQ(boundary_loops(body.mesh()).size(), 1u);
  const std::vector<glm::dvec3> blade{{0.021, 0.05, 0.0}, {0.079, 0.05, 0.0}};
  const CutResult r = cut_surface(body, blade);
  const ValidationReport report = validate(body.mesh());
  ASSERT_TRUE(report.ok()) << report.summary();
  EXPECT_FALSE(r.starts_on_boundary);
  EXPECT_FALSE(r.ends_on_boundary);
  EXPECT_EQ(connected_parts(body.mesh()).size(), 1u);
  const auto loops = boundary_loops(body.mesh());
  ASSERT_EQ(loops.size(), 2u);
  // The new loop runs along the path and back: 2 (path length) - 2 corners.
  bool found = false;
  for (FaceId f : loops) {
    if (face_valence(body.mesh(), f) == 2 * (r.path.size() - 1)) found = true;
  }
  EXPECT_TRUE(found);
  EXPECT_EQ(r.new_vertices.size(), r.path.size() - 2);
}

TEST(SimCutting, DiagonalCutSplitsFacesAndStaysValid) {
  SoftBody body = square();
  const std::vector<glm::dvec3> blade{{0.02, 0.02, 0.0}, {0.08, 0.08, 0.0}};
  const CutResult r = cut_surface(body, blade);
  const ValidationReport report = validate(body.mesh());
  ASSERT_TRUE(report.ok()) << report.summary();
  EXPECT_GT(r.split_faces, 0u);
  EXPECT_EQ(boundary_loops(body.mesh()).size(), 2u);
  EXPECT_EQ(connected_parts(body.mesh()).size(), 1u);
}

TEST(SimCutting, NotchFromTheBoundaryKeepsOneLoop) {
  SoftBody body = square();
  const std::vector<glm::dvec3> blade{{-0.005, 0.05, 0.0}, {0.05, 0.05, 0.0}};
  cut_surface(body, blade);
  ASSERT_TRUE(validate(body.mesh()).ok()) << validate(body.mesh()).summary();
  EXPECT_EQ(boundary_loops(body.mesh()).size(), 1u);
  EXPECT_EQ(connected_parts(body.mesh()).size(), 1u);
}

TEST(SimCutting, ConsecutiveCutsAndSimulationAfterwards) {
  WorldOptions options;
  SimWorld world(options);
  world.add_body(square());
  SoftBody& body = world.body(0);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).y > 0.0999) body.set_anchored(VertexId(i), true);
  }
  const std::uint64_t rebuilds = world.bvh(0).rebuilds();
  const std::vector<glm::dvec3> first{{0.021, 0.03, 0.0}, {0.079, 0.03, 0.0}};
  world.cut(0, first);
  ASSERT_TRUE(validate(body.mesh()).ok());
  const std::vector<glm::dvec3> second{{0.03, 0.061, 0.0}, {0.03, 0.089, 0.0}};
  world.cut(0, second);
  ASSERT_TRUE(validate(body.mesh()).ok()) << validate(body.mesh()).summary();
  EXPECT_EQ(boundary_loops(body.mesh()).size(), 3u);
  EXPECT_GE(world.bvh(0).rebuilds(), rebuilds + 2);
  for (int s = 0; s < 200; ++s)
    world.step({1.0, 1.0, 1.0});
  EXPECT_TRUE(world.take_events().empty());
  for (const auto& p : body.positions())
    EXPECT_TRUE(std::isfinite(p.x + p.y + p.z));
}

TEST(SimCutting, ScalpelSweepCutsWhereTheBladeCrossesTheSurface) {
  WorldOptions options;
  SimWorld world(options);
  world.add_body(square());
  ScalpelSweep sweep;
  for (int s = 0; s <= 20; ++s) {
    const double x = 0.02 + 0.06 * s / 20.0;
    sweep.sample(world.body(0), world.bvh(0), {x, 0.05, 0.005}, {x, 0.05, -0.005});
  }
  EXPECT_EQ(sweep.points().size(), 21u);
  sweep.finish(world.body(0));
  ASSERT_TRUE(validate(world.body(0).mesh()).ok());
  EXPECT_EQ(boundary_loops(world.body(0).mesh()).size(), 2u);
}

TEST(SimCutting, LocalUpdateGivesTheFullRebuildsSpringsAndMasses) {
  // A cut updates springs and masses only around the incision: the result must be what a full
  // rebuild from the new mesh gives (springs exactly, masses to rounding).
  SoftBody body(testing::sphere(24, 8.0), Material{});
  const double c = 0.0115, r = 0.008;
  std::vector<glm::dvec3> blade;
  for (int i = 0; i <= 6; ++i) {
    const double a = -0.5 + i / 6.0;
    blade.emplace_back(c + r * std::sin(a), c, c + r * std::cos(a));
  }
  const CutResult cut = cut_surface(body, blade);
  ASSERT_GT(cut.new_vertices.size(), 0u);
  ASSERT_TRUE(validate(body.mesh()).ok());
  const Dlfl& mesh = body.mesh();
  std::vector<glm::dvec3> rest(mesh.vertex_capacity(), glm::dvec3(0.0));
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    if (mesh.alive(VertexId(i))) rest[i] = body.rest_position(VertexId(i));
  }
  const std::vector<Spring> full = build_springs(mesh, rest, Material{});
  ASSERT_EQ(body.springs().size(), full.size());
  std::size_t on_copies = 0;  // the far lip's copies carry springs of their own
  for (const Spring& s : body.springs()) {
    for (VertexId q : cut.new_vertices)
      on_copies += (s.a == q.idx || s.b == q.idx) ? 1 : 0;
  }
  EXPECT_GE(on_copies, 2 * cut.new_vertices.size());
  for (std::size_t i = 0; i < full.size(); ++i) {
    const Spring& s = body.springs()[i];
    ASSERT_EQ(s.a, full[i].a) << i;
    ASSERT_EQ(s.b, full[i].b) << i;
    EXPECT_EQ(s.kind, full[i].kind) << i;
    EXPECT_EQ(s.rest_m, full[i].rest_m) << i;
    EXPECT_EQ(s.k_N_per_m, full[i].k_N_per_m) << i;
  }
  // Masses: each real face's area shared equally by its corners.
  const Material mat;
  std::vector<double> mass(mesh.vertex_capacity(), 0.0);
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh.alive(f) || mesh.is_bounding(f) || mesh.is_point_sphere(mesh.first_corner(f)))
      continue;
    std::vector<std::uint32_t> ring;
    CornerId k = mesh.first_corner(f);
    do {
      ring.push_back(mesh.vertex(k).idx);
      k = mesh.next(k);
    } while (k != mesh.first_corner(f));
    glm::dvec3 twice_area(0.0);
    for (std::size_t i = 0; i < ring.size(); ++i)
      twice_area += glm::cross(rest[ring[i]], rest[ring[(i + 1) % ring.size()]]);
    for (std::uint32_t v : ring)
      mass[v] += 0.5 * glm::length(twice_area) * mat.density_kg_per_m3 * mat.thickness_m /
                 double(ring.size());
  }
  ASSERT_EQ(body.masses().size(), mass.size());
  for (std::size_t i = 0; i < mass.size(); ++i)
    EXPECT_NEAR(body.masses()[i], mass[i], 1e-12 * mass[i]) << i;
  EXPECT_FALSE(body.closed());  // the incision opened it
}

/// The body's triangles (updated around the cut) against a triangulation of the whole mesh.
void expect_full_triangulation(const SoftBody& body, const char* what) {
  const SurfaceTriangles full = triangulate_surface(body.mesh());
  ASSERT_EQ(body.triangles().size(), full.size()) << what;
  EXPECT_EQ(body.triangles().indices, full.indices) << what;
  EXPECT_TRUE(body.triangles().face_of == full.face_of) << what;
}

TEST(SimCutting, LocalUpdateGivesTheFullTriangulation) {
  // Two arcs on the sphere (triangles), the second crossing the first's end, and two cuts on the
  // sheet (quads: two triangles per face), one from its boundary.
  SoftBody sphere(testing::sphere(24, 8.0), Material{});
  ASSERT_TRUE(sphere.closed());
  const double c = 0.0115, r = 0.008;
  for (const double tilt : {0.0, 0.9}) {
    std::vector<glm::dvec3> blade;
    for (int i = 0; i <= 6; ++i) {
      const double a = -0.5 + i / 6.0;
      const glm::dvec3 along(std::sin(a) * std::cos(tilt), std::sin(a) * std::sin(tilt),
                             std::cos(a));
      blade.push_back(glm::dvec3(c) + r * along);
    }
    cut_surface(sphere, blade);
    ASSERT_TRUE(validate(sphere.mesh()).ok());
    expect_full_triangulation(sphere, "sphere");
    EXPECT_FALSE(sphere.closed());
  }
  SoftBody sheet = square();
  cut_surface(sheet, std::vector<glm::dvec3>{{0.021, 0.03, 0.0}, {0.079, 0.03, 0.0}});
  expect_full_triangulation(sheet, "sheet, inside");
  cut_surface(sheet, std::vector<glm::dvec3>{{0.0, 0.061, 0.0}, {0.04, 0.061, 0.0}});
  ASSERT_TRUE(validate(sheet.mesh()).ok());
  expect_full_triangulation(sheet, "sheet, from the boundary");
  EXPECT_FALSE(sheet.closed());
}

TEST(SimCutting, TooShortCutIsRefusedUnchanged) {
  SoftBody body = square();
  const std::uint64_t version = body.mesh().topology_version();
  const std::vector<glm::dvec3> blade{{0.05, 0.05, 0.0}, {0.0501, 0.05, 0.0}};
  EXPECT_THROW(cut_surface(body, blade), CutError);
  EXPECT_EQ(body.mesh().topology_version(), version);
}

}  // namespace
}  // namespace bisturi::sim
