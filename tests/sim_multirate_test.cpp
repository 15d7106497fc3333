// Multirate stepping (IntegratorOptions::far_field_interval): the analytic checks run
// again with the near region every step and the far field in blocks - the static sag, the
// probe's force against depth and on release, no energy growth, determinism - and the mode's
// own promises: a step solves the region and one block, the far field keeps its time, cuts and
// grasps work.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/grasp.h"
#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr int kInterval = 8;

// The sphere of sim_soft_body_test (radius 6 mm, centre 9.5 mm) on its anchored lower part.
constexpr double kCentre = 0.0095;
constexpr double kTop = kCentre + 0.006;

void anchor_below(SoftBody& body, double z) {
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < z) body.set_anchored(VertexId(i), true);
  }
}

/// The hanging strip of SimSoftBody.HangingStripReachesPredictedSag: the bottom row's sag after
/// 4 s, with the given interval.
double strip_sag(int interval, std::vector<SimEvent>& events) {
  const std::size_t n = 10;
  const double cell_mm = 10.0;
  SoftBody body = testing::hanging_strip(n);
  IntegratorOptions opt;
  opt.cg_relative_tolerance = 1e-9;
  opt.max_cg_iterations = 100;
  opt.far_field_interval = interval;
  ImplicitIntegrator integrator;
  for (int s = 0; s < 4000; ++s)
    integrator.step(body, opt, events);
  const double bottom_rest = -double(n) * cell_mm * kMetresPerMillimetre;
  double sag = 0.0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (std::abs(body.rest_position(v).z - bottom_rest) < 1e-9)
      sag = std::max(sag, bottom_rest - body.position(v).z);
  }
  return sag;
}

TEST(SimMultirate, HangingStripReachesTheSingleRateSag) {
  std::vector<SimEvent> events;
  const double single = strip_sag(1, events);
  const double multi = strip_sag(kInterval, events);
  EXPECT_TRUE(events.empty());
  ASSERT_GT(single, 1e-3);
  EXPECT_NEAR(multi, single, 0.01 * single);
}

/// A world with the firm sphere of the haptic tests (no gravity) under the probe.
SimWorld probe_world(int interval) {
  WorldOptions options;
  options.haptic.max_force_N = 100.0;
  options.haptic.max_force_rate_N_per_s = 1e6;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  options.integrator.far_field_interval = interval;
  SimWorld world(options);
  const std::uint32_t id =
      world.add_body(SoftBody(testing::sphere(24, 8.0), testing::firm_material()));
  anchor_below(world.body(id), 0.0115);
  return world;
}

TEST(SimMultirate, ProbeForceGrowsWithDepthMatchesSingleRateAndVanishesOnRelease) {
  SimWorld multi = probe_world(kInterval);
  SimWorld single = probe_world(1);
  const glm::dvec3 top(0.0115, 0.0115, 0.0115 + 0.008);
  double previous = 0.0;
  for (double depth : {0.0005, 0.001, 0.002, 0.003}) {
    HapticOutput out, reference;
    for (int s = 0; s < 300; ++s) {
      out = multi.step(top - glm::dvec3(0, 0, depth));
      reference = single.step(top - glm::dvec3(0, 0, depth));
    }
    EXPECT_TRUE(out.contact) << depth;
    EXPECT_GT(out.force_N.z, previous) << "depth " << depth;
    EXPECT_NEAR(out.force_N.z, reference.force_N.z, 0.05 * reference.force_N.z) << depth;
    // Only the region and one block were solved in the last step.
    const StepStats& st = multi.last_stats(0);
    EXPECT_LT(st.awake_vertices, st.free_vertices) << depth;
    previous = out.force_N.z;
  }
  HapticOutput out;
  for (int s = 0; s < 50; ++s)
    out = multi.step(top + glm::dvec3(0, 0, 0.01));
  EXPECT_FALSE(out.contact);
  EXPECT_LT(glm::length(out.force_N), 1e-12);
  EXPECT_TRUE(multi.take_events().empty());
}

TEST(SimMultirate, EnergyDoesNotGrowWithoutInput) {
  // Squashed (no gravity, no anchors): it rings, and backward Euler may only lose energy.
  SoftBody body = testing::squashed_sphere();
  IntegratorOptions opt;
  opt.gravity_m_s2 = glm::dvec3(0.0);
  opt.cg_relative_tolerance = 1e-8;
  opt.max_cg_iterations = 200;
  opt.far_field_interval = kInterval;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  double previous = body.total_energy(opt.gravity_m_s2);
  const double initial = previous;
  ASSERT_GT(initial, 0.0);
  for (int s = 0; s < 500; ++s) {
    const StepStats st = integrator.step(body, opt, events);
    ASSERT_LT(st.awake_vertices, st.free_vertices) << "step " << s;  // one block per step
    const double e = body.total_energy(opt.gravity_m_s2);
    ASSERT_LE(e, previous * (1.0 + 1e-6) + 1e-12) << "step " << s;
    previous = e;
  }
  EXPECT_LT(previous, 0.5 * initial);
  EXPECT_TRUE(events.empty());
}

/// The scripted probe of SimSoftBody.DeterministicState, in multirate.
std::uint64_t run_scripted(int steps) {
  WorldOptions options;
  options.integrator.far_field_interval = kInterval;
  SimWorld world(options);
  const std::uint32_t id = world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  anchor_below(world.body(id), kCentre);
  for (int s = 0; s < steps; ++s) {
    const double depth = 0.002 * std::sin(0.01 * s);
    world.step({kCentre, kCentre, kTop + 0.001 - depth});
  }
  EXPECT_TRUE(world.take_events().empty());
  return world.body(id).state_hash();
}

TEST(SimMultirate, DeterministicState) {
  EXPECT_EQ(run_scripted(300), run_scripted(300));
}

TEST(SimMultirate, TheFarFieldSettlesWhereTheSingleRateBodyDoes) {
  // Gravity, no probe: every vertex is in the far field and is solved once per interval with a
  // step of interval x dt, its neighbours held. That relaxes the body's global shape more slowly
  // than one solve over all of it (docs/sim/integrator.md, "Tenth pass": 3 s leave 28 % of the
  // sag still to go, 12 s 5 %), but to the same rest: after 16 s both bodies rest in the same sag.
  auto settle = [](int interval, int steps) {
    Material mat;
    mat.drag_per_s = 20.0;
    SoftBody body(testing::sphere(20, 6.0), mat);
    anchor_below(body, kCentre);
    IntegratorOptions opt;
    opt.far_field_interval = interval;
    ImplicitIntegrator integrator;
    std::vector<SimEvent> events;
    for (int s = 0; s < steps; ++s)
      integrator.step(body, opt, events);
    EXPECT_TRUE(events.empty());
    return std::vector<glm::dvec3>(body.positions().begin(), body.positions().end());
  };
  const std::vector<glm::dvec3> single = settle(1, 3000), multi = settle(kInterval, 16000);
  SoftBody rest(testing::sphere(20, 6.0), Material{});
  double sag = 0.0, differs = 0.0;
  for (std::size_t i = 0; i < single.size(); ++i) {
    sag = std::max(sag, glm::length(single[i] - rest.positions()[i]));
    differs = std::max(differs, glm::length(single[i] - multi[i]));
  }
  ASSERT_GT(sag, 1e-5);
  EXPECT_LT(differs, 0.05 * sag) << "sag " << sag;
}

TEST(SimMultirate, CutsAndGraspsWork) {
  WorldOptions options;
  options.integrator.far_field_interval = kInterval;
  SimWorld world(options);
  const std::uint32_t id = world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  SoftBody& body = world.body(id);
  anchor_below(body, kCentre);
  for (int s = 0; s < 100; ++s)
    world.step({kCentre, kCentre, kTop + 0.0005});
  // A cut over the top along a meridian: the regions are made again for the new topology.
  std::vector<glm::dvec3> blade;
  for (int k = -4; k <= 4; ++k) {
    const double a = 0.12 * k;
    blade.emplace_back(kCentre + 0.006 * std::sin(a), kCentre + 0.0003,
                       kCentre + 0.006 * std::cos(a));
  }
  const CutResult cut = world.cut(id, blade);
  ASSERT_TRUE(validate(body.mesh()).ok());
  EXPECT_FALSE(cut.new_vertices.empty());
  for (int s = 0; s < 200; ++s)
    world.step({kCentre, kCentre, kTop - 0.001});
  EXPECT_LT(world.last_stats(id).awake_vertices, world.last_stats(id).free_vertices);
  // A grasp makes kinematic vertices: those steps are single-rate (every free vertex solved).
  Grasper grasper;
  grasper.jaw_a = {
      {kCentre - 0.001, kCentre, kTop}, {kCentre - 0.001, kCentre, kTop + 0.002}, 0.0005};
  grasper.jaw_b = {
      {kCentre + 0.001, kCentre, kTop}, {kCentre + 0.001, kCentre, kTop + 0.002}, 0.0005};
  Grasp grasp;
  ASSERT_GT(grasp.close(body, grasper, 0.0015), 0u);
  for (int s = 0; s < 50; ++s) {
    grasp.drag(body, {kCentre, kCentre, kTop + 0.0002 * s / 50.0});
    world.step({1.0, 1.0, 1.0});
  }
  EXPECT_EQ(world.last_stats(id).awake_vertices, world.last_stats(id).free_vertices);
  grasp.release(body);
  for (int s = 0; s < 50; ++s)
    world.step({1.0, 1.0, 1.0});
  EXPECT_LT(world.last_stats(id).awake_vertices, world.last_stats(id).free_vertices);
  EXPECT_TRUE(world.take_events().empty());
  for (const auto& p : body.positions())
    ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
}

}  // namespace
}  // namespace bisturi::sim
