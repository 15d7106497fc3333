// The force pass a step takes at its end state for the guard is reused by the next step: reused,
// it gives the state a fresh pass gives bit for bit, and an edit of the state between steps
// (positions, velocities) makes the next step take its own pass.

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <vector>

#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kCentre = 0.0095;  // the test sphere's centre (m), radius 6 mm

SoftBody anchored_sphere() {
  SoftBody body(testing::sphere(20, 6.0), Material{});
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < kCentre - 0.003) body.set_anchored(VertexId(i), true);
  }
  return body;
}

/// Steps the sphere under gravity with a load on its top vertex; when `touch` is set, takes the
/// non-const view of the positions between steps (an edit that changes nothing), so that no step
/// can reuse the last one's end pass. Returns the final state's hash and counts the steps that
/// reused it.
std::uint64_t run(bool touch, int steps, int& reused_steps) {
  SoftBody body = anchored_sphere();
  const VertexId top = VertexId(0);
  ImplicitIntegrator integrator;
  IntegratorOptions options;
  options.sleeping = false;
  std::vector<SimEvent> events;
  reused_steps = 0;
  for (int s = 0; s < steps; ++s) {
    if (touch) (void)body.positions();
    body.add_force(top, glm::dvec3(0.0, 0.0, s < steps / 2 ? -2e-3 : 0.0));
    const StepStats stats =
        integrator.step(body, options, events, 0, static_cast<std::uint64_t>(s));
    if (stats.reused_end_pass) ++reused_steps;
  }
  EXPECT_TRUE(events.empty());
  return body.state_hash();
}

TEST(SimEndPass, ReusedPassGivesTheSameStateAsAFreshOne) {
  int reused_steps = 0, fresh_steps = 0;
  const std::uint64_t reused = run(false, 60, reused_steps);
  const std::uint64_t fresh = run(true, 60, fresh_steps);
  EXPECT_EQ(reused_steps, 59);  // every step but the first
  EXPECT_EQ(fresh_steps, 0);
  EXPECT_EQ(reused, fresh);
}

TEST(SimEndPass, NonConstViewsAndSettersCountAsEdits) {
  SoftBody body = anchored_sphere();
  const SoftBody& view = body;
  std::uint64_t edits = body.state_edits();
  (void)view.positions();
  (void)view.velocities();
  EXPECT_EQ(body.state_edits(), edits);
  (void)body.positions();
  EXPECT_GT(body.state_edits(), edits);
  edits = body.state_edits();
  (void)body.velocities();
  EXPECT_GT(body.state_edits(), edits);
  edits = body.state_edits();
  body.set_position(VertexId(0), body.position(VertexId(0)));
  EXPECT_GT(body.state_edits(), edits);
  edits = body.state_edits();
  body.set_velocity(VertexId(0), glm::dvec3(0.0));
  EXPECT_GT(body.state_edits(), edits);
}

// A vertex pulled 1 mm out between two steps must be pulled back by the next step: with the
// last step's forces (taken before the pull, at rest) it would barely move.
TEST(SimEndPass, AnEditBetweenStepsIsSeenByTheNextStep) {
  SoftBody body = anchored_sphere();
  ImplicitIntegrator integrator;
  IntegratorOptions options;
  options.sleeping = false;
  options.gravity_m_s2 = glm::dvec3(0.0);  // the rest shape is an equilibrium
  std::vector<SimEvent> events;
  for (int s = 0; s < 5; ++s)
    (void)integrator.step(body, options, events, 0, static_cast<std::uint64_t>(s));
  // The free vertex highest up, pulled outward along +z.
  VertexId top = VertexId(0);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mass(v) > 0.0 && !body.anchored(v) && body.position(v).z > body.position(top).z)
      top = v;
  }
  ASSERT_LT(std::abs(body.velocity(top).z), 1e-6);
  body.set_position(top, body.position(top) + glm::dvec3(0.0, 0.0, 1e-3));
  const StepStats stats = integrator.step(body, options, events, 0, 5);
  EXPECT_FALSE(stats.reused_end_pass);
  EXPECT_TRUE(events.empty());
  // Measured: -0.21 m/s; with the stale forces (a broken count) it stays at 0.
  EXPECT_LT(body.velocity(top).z, -0.01);
}

// In a world, each body keeps its own end pass: two bodies stepped in turn both reuse theirs,
// with the haptic probe pressing one of them (loads are not edits of the state).
TEST(SimEndPass, EachBodyOfAWorldReusesItsOwnPass) {
  WorldOptions options;
  options.integrator.sleeping = false;
  SimWorld world(options);
  for (int b = 0; b < 2; ++b) {
    SoftBody body = anchored_sphere();
    for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
      body.set_position(VertexId(i), body.position(VertexId(i)) + glm::dvec3(0.02 * b, 0, 0));
    world.add_body(std::move(body));
  }
  const double top = kCentre + 0.006;
  int touching = 0;
  for (int s = 0; s < 20; ++s) {
    const HapticOutput out = world.step({kCentre, kCentre, top - 0.001 * (s % 3)});
    touching += out.contact && out.body == 0 ? 1 : 0;
    if (s == 0) continue;
    EXPECT_TRUE(world.last_stats(0).reused_end_pass) << "step " << s;
    EXPECT_TRUE(world.last_stats(1).reused_end_pass) << "step " << s;
  }
  EXPECT_GT(touching, 5);
  EXPECT_TRUE(world.take_events().empty());
}

}  // namespace
}  // namespace bisturi::sim
