// Haptic rendering and collision: a probe pressed into a sphere gets a force that grows with
// depth and vanishes on release; the force is clamped and ramped; a grasper drags tissue; two
// touching bodies push each other apart; the BVH refits every step and rebuilds after a cut.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include <glm/geometric.hpp>

#include "bisturi/sim/cutting.h"
#include "bisturi/sim/grasp.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kCentre = 0.0115;  // sphere(24, ...) is centred at 11.5 mm
constexpr double kRadius = 0.008;

/// `bound`: the springs' bound Hessian (SpringHessian::Bound), for the checks of a force that
/// grows with depth to 3 mm: with the clamped one the membrane sphere buckles under the probe
/// between 1 and 2 mm (a surface without an interior, docs/sim/integrator.md).
SimWorld sphere_world(const HapticOptions& haptic, bool bound = false) {
  WorldOptions options;
  options.haptic = haptic;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);  // the probe alone loads the tissue
  if (bound) {
    options.integrator.spring_hessian = SpringHessian::Bound;
    options.integrator.cg_warm_start = true;
  }
  SimWorld world(options);
  const std::uint32_t id =
      world.add_body(SoftBody(testing::sphere(24, 8.0), testing::firm_material()));
  SoftBody& body = world.body(id);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < kCentre) body.set_anchored(VertexId(i), true);
  }
  return world;
}

TEST(SimHaptic, ProbeForceGrowsWithDepthAndVanishesOnRelease) {
  HapticOptions haptic;
  haptic.max_force_N = 100.0;
  haptic.max_force_rate_N_per_s = 1e6;
  SimWorld world = sphere_world(haptic, true);
  const glm::dvec3 top(kCentre, kCentre, kCentre + kRadius);
  HapticOutput out = world.step(top + glm::dvec3(0, 0, 0.003));
  EXPECT_FALSE(out.contact);
  EXPECT_EQ(out.force_N, glm::dvec3(0.0));
  double previous = 0.0;
  for (double depth : {0.0005, 0.001, 0.002, 0.003}) {
    for (int s = 0; s < 300; ++s)
      out = world.step(top - glm::dvec3(0, 0, depth));
    EXPECT_TRUE(out.contact) << depth;
    EXPECT_GT(out.force_N.z, previous) << "depth " << depth;  // pushes the probe back out
    EXPECT_LT(std::abs(out.force_N.x) + std::abs(out.force_N.y), 0.2 * out.force_N.z);
    previous = out.force_N.z;
  }
  for (int s = 0; s < 50; ++s)
    out = world.step(top + glm::dvec3(0, 0, 0.01));
  EXPECT_FALSE(out.contact);
  EXPECT_LT(glm::length(out.force_N), 1e-12);
  EXPECT_TRUE(world.take_events().empty());
}

// The force sent is the coupling's at the end of the step: the touched patch gave way under the
// reaction during the solve, the proxy rode down with it, and the device gets what the tissue
// ended the step with, not the larger force the step started from.
TEST(SimHaptic, ForceIsTheReactionTheTissueEndedTheStepWith) {
  HapticOptions haptic;
  haptic.max_force_N = 100.0;
  haptic.max_force_rate_N_per_s = 1e6;
  SimWorld world = sphere_world(haptic);
  const SoftBody& body = world.body(0);
  double top_z = 0.0;
  for (const glm::dvec3& p : body.positions())
    top_z = std::max(top_z, p.z);
  world.step(glm::dvec3(kCentre, kCentre, top_z + 0.005));  // the proxy starts outside
  const glm::dvec3 device(kCentre, kCentre, top_z - 0.001);
  // At the start of the step the probe (radius r) is r + 1 mm into the flat top.
  const double start_force = haptic.coupling_N_per_m * (haptic.probe_radius_m + 0.001);
  const HapticOutput out = world.step(device);
  ASSERT_TRUE(out.contact);
  double top_after = 0.0;
  for (const glm::dvec3& p : body.positions())
    top_after = std::max(top_after, p.z);
  std::printf("start %.4f N, end %.4f N, top moved %.4f mm\n", start_force, out.force_N.z,
              1e3 * (top_after - top_z));
  EXPECT_LT(top_after, top_z);  // the patch gave way
  EXPECT_GT(out.force_N.z, 0.0);
  EXPECT_LT(out.force_N.z, start_force - 0.5 * haptic.coupling_N_per_m * (top_z - top_after));
  // Force, proxy and depth agree: the coupling spring between the device and the moved proxy.
  const glm::dvec3 spring = haptic.coupling_N_per_m * (out.proxy_m - device);
  EXPECT_NEAR(glm::length(out.force_N - spring), 0.0, 1e-9 * glm::length(spring));
  EXPECT_NEAR(out.depth_m * haptic.coupling_N_per_m, glm::length(out.force_N), 1e-9);
}

TEST(SimHaptic, ForceIsClampedAndRamped) {
  HapticOptions haptic;
  haptic.max_force_N = 0.5;
  haptic.max_force_rate_N_per_s = 100.0;  // 0.1 N per 1 ms step
  haptic.apply_reaction = false;
  SimWorld world = sphere_world(haptic);
  const glm::dvec3 top(kCentre, kCentre, kCentre + kRadius);
  world.step(top + glm::dvec3(0, 0, 0.002));
  glm::dvec3 last(0.0);
  double peak = 0.0;
  for (int s = 0; s < 40; ++s) {
    const HapticOutput out = world.step(top - glm::dvec3(0, 0, 0.004));  // a sudden deep jump
    EXPECT_LE(glm::length(out.force_N - last), 0.1 + 1e-12) << "step " << s;
    EXPECT_LE(glm::length(out.force_N), 0.5 + 1e-12);
    peak = std::max(peak, glm::length(out.force_N));
    last = out.force_N;
  }
  EXPECT_NEAR(peak, 0.5, 1e-9);
}

TEST(SimHaptic, FrozenBodyGivesNoForce) {
  SimWorld world = sphere_world(HapticOptions{});
  world.body(0).freeze();
  const glm::dvec3 top(kCentre, kCentre, kCentre + kRadius);
  const HapticOutput out = world.step(top - glm::dvec3(0, 0, 0.002));
  EXPECT_FALSE(out.contact);
  EXPECT_EQ(out.force_N, glm::dvec3(0.0));
}

// A vessel decimated to facets its whole length long (a tube of 16 slivers, 60 mm by 2.4 mm):
// the probe pressing its middle loads the facets round the one it touches, and pushes along
// their normal, not on the whole tube with the mean of its sides.
TEST(SimHaptic, AProbeOnASliverLoadsTheFacetsRoundIt) {
  SoftBody tube(build_oriented_manifold(tube_mesh(6.0, 60.0, 16, 1)), testing::firm_material());
  const CollisionDevice device;
  const SurfaceBvh bvh(device, tube);
  HapticOptions options;
  options.probe_radius_m = 0.0015;
  options.max_force_N = 100.0;
  options.max_force_rate_N_per_s = 1e9;
  HapticProxy proxy(options);
  const TouchTarget target{&tube, &bvh};
  // From outside, then 0.5 mm into the facets over +x at the tube's middle.
  const glm::dvec3 outside(0.010, 0.0, 0.030);
  (void)proxy.update(outside, {&target, 1}, 0.001);
  const glm::dvec3 into(0.006 + 0.0015 - 0.0005, 0.0, 0.030);
  const HapticOutput out = proxy.update(into, {&target, 1}, 0.001);
  ASSERT_TRUE(out.contact);
  EXPECT_GT(out.force_N.x, 0.98 * glm::length(out.force_N)) << "the tube's normal there";
  std::size_t loaded = 0, far_side = 0;
  glm::dvec3 reaction(0.0);
  for (std::uint32_t i = 0; i < tube.mesh().vertex_capacity(); ++i) {
    const glm::dvec3& f = tube.external_forces()[i];
    if (glm::length(f) == 0.0) continue;
    ++loaded;
    far_side += tube.position(VertexId(i)).x <= 0.0 ? 1 : 0;
    reaction += f;
  }
  EXPECT_GT(loaded, 0u);
  EXPECT_EQ(far_side, 0u) << "the facets round the touched one, not the tube";
  EXPECT_LT(glm::length(reaction + out.force_N), 1e-9 * glm::length(out.force_N));
}

TEST(SimGrasp, GrasperDragsHeldVertices) {
  SimWorld world = sphere_world(HapticOptions{});
  SoftBody& body = world.body(0);
  const glm::dvec3 top(kCentre, kCentre, kCentre + kRadius);
  Grasper g{{top + glm::dvec3(-0.001, 0, 0.004), top + glm::dvec3(-0.001, 0, 0), 0.0008},
            {top + glm::dvec3(0.001, 0, 0.004), top + glm::dvec3(0.001, 0, 0), 0.0008}};
  Grasp grasp;
  ASSERT_GT(grasp.close(body, g, 0.001), 0u);
  const VertexId held = grasp.held().front();
  const glm::dvec3 before = body.position(held);
  for (int s = 1; s <= 200; ++s) {
    grasp.drag(body, top + glm::dvec3(0, 0, 0.005 * s / 200.0));
    world.step(top + glm::dvec3(0.05, 0, 0));  // probe far away
  }
  EXPECT_NEAR(body.position(held).z - before.z, 0.005, 1e-9);
  grasp.release(body);
  EXPECT_FALSE(body.kinematic(held));
  EXPECT_TRUE(world.take_events().empty());
}

TEST(SimCollision, AFineSheetSunkIntoACoarseFaceGetsOneContactPerVertexPushingItOut) {
  // A 20 mm sheet of 0.5 mm cells 0.2 mm under the top face of a 30 mm cube of twelve triangles:
  // each of its 3,200 triangles pairs with the face's two, and every one of its 1,681 vertices
  // is inside and must be pushed out along the face's normal, once.
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  world.add_body(SoftBody(build_oriented_manifold(cube_mesh({0.0, 0.0, 0.0}, 30.0)), Material{}));
  world.add_body(SoftBody(testing::sheet(40, 40, 0.5), Material{}));
  for (auto& p : world.body(1).positions())
    p += glm::dvec3(0.005, 0.005, 0.0298);
  const std::vector<glm::dvec3> before = world.body(1).positions();
  world.step({1.0, 1.0, 1.0});
  const std::size_t sheet_vertices = before.size();
  ASSERT_EQ(sheet_vertices, 41u * 41u);
  // The sheet's vertices, and at most the cube's eight corners the other way.
  EXPECT_GE(world.last_contacts(), sheet_vertices);
  EXPECT_LE(world.last_contacts(), sheet_vertices + 8);
  for (std::size_t i = 0; i < sheet_vertices; ++i) {
    const glm::dvec3 moved = world.body(1).positions()[i] - before[i];
    ASSERT_GT(moved.z, 0.0) << "vertex " << i;
    ASSERT_LT(std::abs(moved.x) + std::abs(moved.y), 0.1 * moved.z) << "vertex " << i;
  }
}

TEST(SimCollision, TouchingBodiesPushApartAndBvhFollows) {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  // Second sphere overlapping the first by 1 mm along x.
  for (auto& p : world.body(1).positions())
    p.x += 0.011;
  const std::uint64_t rebuilds = world.bvh(1).rebuilds();
  double gap_before = 0.0;
  for (auto& p : world.body(1).positions())
    gap_before += p.x;
  world.step({1.0, 1.0, 1.0});
  EXPECT_GT(world.last_contacts(), 0u);
  for (int s = 0; s < 100; ++s)
    world.step({1.0, 1.0, 1.0});
  double gap_after = 0.0;
  for (auto& p : world.body(1).positions())
    gap_after += p.x;
  EXPECT_GT(gap_after, gap_before);              // pushed away along +x
  EXPECT_EQ(world.bvh(1).rebuilds(), rebuilds);  // refits only
  EXPECT_GE(world.bvh(1).refits(), 100u);
}

TEST(SimCollision, AfterACutTheBodiesMeetOnTheTrianglesFreshBvhsFind) {
  CollisionDevice device;
  SoftBody cut_body(testing::sphere(20, 6.0), Material{});
  SoftBody other(testing::sphere(20, 6.0), Material{});
  for (auto& p : other.positions())
    p.x += 0.011;  // 1 mm into the first
  SurfaceBvh cut_bvh(device, cut_body), other_bvh(device, other);
  constexpr double kMargin_m = 0.002;  // wide: the wound's walls meet the other sphere
  EXPECT_FALSE(cut_bvh.overlapping_triangles(cut_body, other_bvh, other, kMargin_m).empty());
  // A cut 3 mm deep across the first sphere's side where the two meet: its walls add triangles
  // (the user geometry rtcCollide works on is kept, its primitive count changed).
  const double c = 0.0095, r = 0.006;
  std::vector<glm::dvec3> blade, tips;
  for (int i = 0; i <= 6; ++i) {
    const double a = -0.35 + 0.7 * i / 6.0;
    blade.emplace_back(c + r * std::cos(a), c + 0.0003, c + r * std::sin(a));
    tips.push_back(c + (r - 0.003) * glm::dvec3(std::cos(a), 0.0, std::sin(a)) +
                   glm::dvec3(0.0, 0.0003, 0.0));
  }
  const std::size_t triangles_before = cut_body.triangles().indices.size();
  CutOptions walls;
  walls.blade_tips_m = tips;
  ASSERT_FALSE(cut_surface(cut_body, blade, walls).path.empty());
  const std::size_t triangles_after = cut_body.triangles().indices.size();
  ASSERT_GT(triangles_after, triangles_before);
  cut_bvh.update(cut_body);
  const auto kept = cut_bvh.overlapping_triangles(cut_body, other_bvh, other, kMargin_m);
  SurfaceBvh fresh_cut(device, cut_body), fresh_other(device, other);
  const auto fresh = fresh_cut.overlapping_triangles(cut_body, fresh_other, other, kMargin_m);
  EXPECT_TRUE(std::any_of(fresh.begin(), fresh.end(), [&](const auto& pair) {
    return 3 * std::size_t{pair.first} >= triangles_before;
  })) << "no wall meets the other sphere";
  EXPECT_EQ(kept, fresh);
}

}  // namespace
}  // namespace bisturi::sim
