// Multirate stepping (IntegratorOptions::far_field_interval): the analytic checks run
// again with the near region every step and the far field one longer step per period - the
// static sag, the probe's force against depth and on release, no energy growth, determinism -
// and the mode's own promises: a step solves the near region, the far field is the single-rate
// step of the interval and settles where the single-rate body does, cuts and grasps work.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

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

/// A world with the firm sphere of the haptic tests (no gravity) under the probe. The springs'
/// bound Hessian: with the clamped one the membrane sphere buckles under the probe between 1
/// and 2 mm (its force drops with depth: a surface without an interior, docs/sim/integrator.md),
/// and this test is about the multirate force following the single-rate one.
SimWorld probe_world(int interval) {
  WorldOptions options;
  options.haptic.max_force_N = 100.0;
  options.haptic.max_force_rate_N_per_s = 1e6;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  options.integrator.spring_hessian = SpringHessian::Bound;
  options.integrator.cg_warm_start = true;
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
    // Only the near region was solved in the last step (not a period's start).
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
  // Squashed (no gravity, no anchors): it rings, and backward Euler may only lose energy. No
  // load, so no near region: the body takes the far field's results, each over the period
  // after the one it was solved in, a block of aggregates per step. At a period's last step
  // every block has the same result, and that state's energy may only fall. (In between, two
  // results meet at the blocks' borders: a body ringing this fast shows it in its energy.)
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
    // Only the blocks move (the first period has no result yet).
    const int phase = s % kInterval;
    EXPECT_EQ(st.awake_vertices > 0, s >= kInterval && phase != 0) << "step " << s;
    EXPECT_LT(st.awake_vertices, st.free_vertices) << "step " << s;
    if (phase != kInterval - 1) continue;
    const double e = body.total_energy(opt.gravity_m_s2);
    ASSERT_LE(e, previous * (1.0 + 1e-6) + 1e-12) << "step " << s;
    previous = e;
  }
  EXPECT_LT(previous, 0.5 * initial);
  EXPECT_TRUE(events.empty());
}

TEST(SimMultirate, AFarFieldThatDivergesIsReportedAndFreezesTheBody) {
  SoftBody body = testing::squashed_sphere();
  IntegratorOptions opt;
  opt.far_field_interval = kInterval;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < 2 * kInterval; ++s)
    integrator.step(body, opt, events);
  ASSERT_TRUE(events.empty());
  // A vertex far from any load goes bad: only the far field's solve meets it.
  body.set_position(VertexId(3), glm::dvec3(std::nan(""), 0.0, 0.0));
  for (int s = 0; s < 2 * kInterval && !body.frozen(); ++s)
    integrator.step(body, opt, events, 7, 100 + std::uint64_t(s));
  ASSERT_TRUE(body.frozen());
  ASSERT_FALSE(events.empty());
  EXPECT_EQ(events.back().kind, SimEventKind::Frozen);
  for (const SimEvent& e : events) {
    EXPECT_EQ(e.body, 7u);
    EXPECT_EQ(e.reason.rfind("far field: ", 0), 0u) << e.reason;
  }
  EXPECT_NE(events.front().reason.find("non-finite"), std::string::npos) << events.front().reason;
}

TEST(SimMultirate, AnIntegratorLeftPartWayThroughAPeriodEndsItsJob) {
  // The first job has no time estimate yet, so after two steps it is likely part-way in its
  // fiber: the integrator's end (its far field's) runs it to its end first. A smoke test (the
  // sanitizer build runs it too); nothing here can see whether the job was part-way.
  SoftBody body = testing::squashed_sphere();
  IntegratorOptions opt;
  opt.far_field_interval = kInterval;
  std::vector<SimEvent> events;
  {
    ImplicitIntegrator integrator;
    integrator.step(body, opt, events);
    integrator.step(body, opt, events);
  }
  EXPECT_TRUE(events.empty());
  // And a new one takes the body on.
  ImplicitIntegrator again;
  for (int s = 0; s < 3 * kInterval; ++s)
    again.step(body, opt, events);
  EXPECT_TRUE(events.empty());
  for (const auto& p : body.positions())
    ASSERT_TRUE(std::isfinite(p.x + p.y + p.z));
}

/// The scripted probe of SimSoftBody.DeterministicState, in multirate.
std::uint64_t run_scripted(int steps, double far_step_budget_s = 0.4e-3) {
  WorldOptions options;
  options.integrator.far_field_interval = kInterval;
  options.integrator.far_step_budget_s = far_step_budget_s;
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

// The far job's time budget moves where its slices end (with 1 s each job ends in its period's
// first step; with none, each step runs its even share), never the state.
TEST(SimMultirate, TheStepBudgetChangesOnlyTheTiming) {
  const std::uint64_t even = run_scripted(300, 0.0);
  EXPECT_EQ(run_scripted(300, 1.0), even);
  EXPECT_EQ(run_scripted(300, 0.4e-3), even);
}

/// The 6 mm sphere with drag, on its anchored lower half.
SoftBody dragged_sphere() {
  Material mat;
  mat.drag_per_s = 20.0;
  SoftBody body(testing::sphere(20, 6.0), mat);
  anchor_below(body, kCentre);
  return body;
}

/// dragged_sphere() under gravity after `steps` steps.
std::vector<glm::dvec3> settled(int interval, double dt, int steps) {
  SoftBody body = dragged_sphere();
  IntegratorOptions opt;
  opt.far_field_interval = interval;
  opt.dt_s = dt;
  opt.sleeping = false;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < steps; ++s)
    integrator.step(body, opt, events);
  EXPECT_TRUE(events.empty());
  return {body.positions().begin(), body.positions().end()};
}

/// The largest distance between the two states' vertices, against the largest displacement of
/// `reference` from `origin` (infinite when it did not move).
double relative_difference(const std::vector<glm::dvec3>& reference,
                           const std::vector<glm::dvec3>& other,
                           const std::vector<glm::dvec3>& origin) {
  double moved = 0.0, differs = 0.0;
  for (std::size_t i = 0; i < reference.size(); ++i) {
    moved = std::max(moved, glm::length(reference[i] - origin[i]));
    differs = std::max(differs, glm::length(reference[i] - other[i]));
  }
  return moved > 0.0 ? differs / moved : std::numeric_limits<double>::infinity();
}

/// The 6 mm sphere's rest positions.
std::vector<glm::dvec3> rest_positions() {
  const SoftBody rest(testing::sphere(20, 6.0), Material{});
  return rest.positions();
}

TEST(SimMultirate, WithoutLoadsTheFarFieldIsTheSingleRateStepOfTheInterval) {
  // Gravity, no probe: no near region, so the body follows the far field's solves, one
  // single-rate step of interval x dt per interval. They differ from a single-rate body stepped
  // so only in the rounding of the solve's parts, which moves where the CG stops within its
  // tolerance (1e-4). A job's result is applied over the period after the one it ran in: the
  // 375 periods of 3000 steps have applied 374 of them.
  const std::vector<glm::dvec3> multi = settled(kInterval, 1e-3, 3000);
  const std::vector<glm::dvec3> single = settled(1, kInterval * 1e-3, 3000 / kInterval - 1);
  EXPECT_LT(relative_difference(single, multi, rest_positions()), 1e-4);
}

TEST(SimMultirate, ChangedOptionsStartAPeriodWithThem) {
  // A session lengthens dt when it falls behind: the far field's next job takes the new step
  // (N times it) from the body's state, and its result is the single-rate step of that length.
  SoftBody body = dragged_sphere();
  IntegratorOptions opt;
  opt.far_field_interval = kInterval;
  // Solved to convergence, so that the result does not hang on the CG's warm start.
  opt.max_cg_iterations = 200;
  opt.cg_relative_tolerance = 1e-10;
  opt.cg_weight_fraction = 1e-12;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < 3 * kInterval + 3; ++s)
    integrator.step(body, opt, events);
  opt.dt_s = 2e-3;
  const SoftBody start(body);  // the state the next job starts from
  // That job's period, then the next, over which its result is applied block by block.
  for (int s = 0; s < 2 * kInterval; ++s)
    integrator.step(body, opt, events);
  EXPECT_TRUE(events.empty());
  SoftBody reference(start);
  IntegratorOptions single = opt;
  single.far_field_interval = 1;
  single.sleeping = false;
  single.dt_s = kInterval * 2e-3;
  ImplicitIntegrator other;
  other.step(reference, single, events);
  EXPECT_LT(relative_difference(std::as_const(reference).positions(),
                                std::as_const(body).positions(), start.positions()),
            1e-4);
}

TEST(SimMultirate, AnEditFromOutsideKeepsTheNearRegion) {
  // The far field starts a new period from the edited state; the near region keeps its
  // aggregates for their linger time all the same.
  SoftBody body = dragged_sphere();
  IntegratorOptions opt;
  opt.far_field_interval = kInterval;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  VertexId top(0);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z > body.position(top).z) top = VertexId(i);
  }
  for (int s = 0; s < 3 * kInterval + 2; ++s) {
    body.add_force(top, {0.0, 0.0, -0.01});
    integrator.step(body, opt, events);
  }
  body.set_position(top, body.position(top));               // an edit, as a caller's
  const StepStats st = integrator.step(body, opt, events);  // no load now
  EXPECT_GT(st.awake_vertices, 0u);
  EXPECT_LT(st.awake_vertices, st.free_vertices);
  EXPECT_TRUE(events.empty());
}

TEST(SimMultirate, TheFarFieldSettlesWhereTheSingleRateBodyDoes) {
  // The far field's longer step relaxes the body's global shape more slowly (backward Euler
  // with the springs' bound Hessian moves less per unit of time with a longer step:
  // docs/sim/integrator.md, "Multirate stepping"), to the same rest: after 16 s both rest in the
  // same sag.
  const std::vector<glm::dvec3> single = settled(1, 1e-3, 3000);
  EXPECT_LT(relative_difference(single, settled(kInterval, 1e-3, 16000), rest_positions()), 0.05);
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
