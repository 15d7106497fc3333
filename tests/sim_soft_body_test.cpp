// Soft tissue: static sag of a hanging strip against the spring model's prediction, no energy
// growth without input, determinism, and the divergence guard's rollback and freeze reports.

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

TEST(SimSoftBody, HangingStripReachesPredictedSag) {
  // A one-cell-wide strip of n quads hangs from its top row. With structural springs only (no
  // shear, no bending) the two columns are mirror images, the horizontal springs keep their rest
  // length, and each column is a chain: segment j carries the weight of the rows below it, so
  // the bottom row sags by sum_j g * (mass below j) / k.
  const std::size_t n = 10;
  const double cell_mm = 10.0;
  SoftBody body = testing::hanging_strip(n);
  const Material& mat = body.material();
  const Dlfl& mesh = body.mesh();
  IntegratorOptions opt;
  opt.cg_relative_tolerance = 1e-9;
  opt.max_cg_iterations = 100;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < 4000; ++s)
    integrator.step(body, opt, events);
  EXPECT_TRUE(events.empty());

  // Prediction from the lumped masses: area density x cell area / 4 per face corner.
  const double area = (cell_mm * kMetresPerMillimetre) * (cell_mm * kMetresPerMillimetre);
  const double quarter = mat.density_kg_per_m3 * mat.thickness_m * area / 4.0;
  std::vector<double> row_mass(n + 1, 2.0 * quarter);  // per column: two faces' corners
  row_mass[n] = quarter;
  double sag = 0.0;
  for (std::size_t j = 1; j <= n; ++j) {
    double below = 0.0;
    for (std::size_t i = j; i <= n; ++i)
      below += row_mass[i];
    sag += 9.81 * below / mat.structural_N_per_m;
  }
  const double bottom_rest = -double(n) * cell_mm * kMetresPerMillimetre;
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (std::abs(body.rest_position(v).z - bottom_rest) > 1e-9) continue;
    const double measured = bottom_rest - body.position(v).z;
    EXPECT_NEAR(measured, sag, 0.01 * sag) << "vertex " << i;
  }
  EXPECT_GT(sag, 1e-3);  // a visible sag, not a rounding effect
}

TEST(SimSoftBody, BodyAtRestCostsAtMostTwoIterations) {
  // A sphere resting on its anchored lower half, settled with the default options: its residual
  // force is a small fraction of its weight, and the absolute criterion ends the solve at once
  // (the relative one alone ran to the iteration cap on a right-hand side of rounding noise).
  Material mat;
  mat.drag_per_s = 20.0;  // settles in a fraction of a second
  SoftBody body(testing::sphere(20, 6.0), mat);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < 0.0095) body.set_anchored(VertexId(i), true);
  }
  const IntegratorOptions defaults;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < 3000; ++s)
    integrator.step(body, defaults, events);
  int most = 0;
  for (int s = 0; s < 50; ++s)
    most = std::max(most, integrator.step(body, defaults, events).cg_iterations);
  EXPECT_LE(most, 2);
  EXPECT_TRUE(events.empty());
}

TEST(SimSoftBody, EnergyDoesNotGrowWithoutInput) {
  // Squashed (no gravity, no anchors): it rings, and backward Euler may only lose energy.
  SoftBody body = testing::squashed_sphere();
  IntegratorOptions opt;
  opt.gravity_m_s2 = glm::dvec3(0.0);
  opt.cg_relative_tolerance = 1e-8;
  opt.max_cg_iterations = 200;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  double previous = body.total_energy(opt.gravity_m_s2);
  const double initial = previous;
  ASSERT_GT(initial, 0.0);
  for (int s = 0; s < 500; ++s) {
    integrator.step(body, opt, events);
    const double e = body.total_energy(opt.gravity_m_s2);
    ASSERT_LE(e, previous * (1.0 + 1e-6) + 1e-12) << "step " << s;
    previous = e;
  }
  EXPECT_LT(previous, initial);
  EXPECT_TRUE(events.empty());
}

std::uint64_t run_scripted(int steps) {
  WorldOptions options;
  SimWorld world(options);
  const std::uint32_t id = world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  SoftBody& body = world.body(id);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < 0.0095) body.set_anchored(VertexId(i), true);
  }
  for (int s = 0; s < steps; ++s) {
    const double depth = 0.002 * std::sin(0.01 * s);
    world.step({0.0095, 0.0095, 0.0095 + 0.006 + 0.001 - depth});
  }
  return body.state_hash();
}

TEST(SimSoftBody, DeterministicState) {
  const std::uint64_t a = run_scripted(300);
  const std::uint64_t b = run_scripted(300);
  EXPECT_EQ(a, b);
}

TEST(SimSoftBody, DivergenceIsRolledBackThenFrozenAndReported) {
  SoftBody body(testing::sheet(4, 4, 10.0), Material{});
  ImplicitIntegrator integrator;
  IntegratorOptions opt;
  std::vector<SimEvent> events;
  integrator.step(body, opt, events);
  const std::uint64_t good = body.state_hash();
  ASSERT_TRUE(events.empty());
  // A non-finite force: every retry fails, the body is restored and frozen.
  body.add_force(VertexId(5), glm::dvec3(std::nan(""), 0.0, 0.0));
  const StepStats stats = integrator.step(body, opt, events, 3, 42);
  EXPECT_TRUE(stats.frozen);
  EXPECT_TRUE(body.frozen());
  ASSERT_EQ(events.size(), std::size_t(opt.max_retry_halvings) + 2);
  for (int i = 0; i <= opt.max_retry_halvings; ++i) {
    EXPECT_EQ(events[i].kind, SimEventKind::RolledBack);
    EXPECT_EQ(events[i].substeps, 1 << i);
    EXPECT_EQ(events[i].body, 3u);
    EXPECT_EQ(events[i].step, 42u);
  }
  EXPECT_EQ(events.back().kind, SimEventKind::Frozen);
  for (const auto& p : body.positions())
    EXPECT_TRUE(std::isfinite(p.x + p.y + p.z));
  for (const auto& v : body.velocities())
    EXPECT_EQ(v, glm::dvec3(0.0));
  (void)good;
  // Frozen: later steps do nothing and report nothing.
  events.clear();
  const std::uint64_t frozen_hash = body.state_hash();
  integrator.step(body, opt, events);
  EXPECT_EQ(body.state_hash(), frozen_hash);
  EXPECT_TRUE(events.empty());
}

TEST(SimSoftBody, EnergyJumpIsRolledBackAndRetriedWithSubsteps) {
  // A huge stiffness with a one-iteration solve leaves a bad step; the guard's energy check sees
  // the rise beyond the external work and retries with smaller substeps.
  Material mat;
  mat.structural_N_per_m = 1e6;
  mat.drag_per_s = 0.0;
  mat.spring_damping_N_s_per_m = 0.0;
  SoftBody body(testing::sheet(6, 6, 10.0), mat);
  for (auto& p : body.positions())
    p *= 1.3;  // stretched 30 %
  IntegratorOptions opt;
  opt.gravity_m_s2 = glm::dvec3(0.0);
  opt.max_cg_iterations = 1;
  opt.energy_jump_relative = 0.0;
  opt.energy_jump_J = 0.0;
  ImplicitIntegrator integrator;
  std::vector<SimEvent> events;
  for (int s = 0; s < 50 && events.empty(); ++s)
    integrator.step(body, opt, events);
  // Either the guard caught a rise (and reported it) or the truncated solve never raised the
  // energy; both are acceptable outcomes, but a report must name a reason.
  for (const SimEvent& e : events)
    EXPECT_FALSE(e.reason.empty());
  for (const auto& p : body.positions())
    EXPECT_TRUE(std::isfinite(p.x + p.y + p.z));
}

}  // namespace
}  // namespace bisturi::sim
