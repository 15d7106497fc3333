// Sleeping volume bodies (volume_body.h, VolumeOptions::sleep_speed_m_s): an organ at rest on
// its anchors stops costing steps, stays where it settled, and wakes within the step a load
// reaches it, as it would have moved awake.

#include <gtest/gtest.h>

#include <algorithm>
#include <vector>

#include <glm/geometric.hpp>

#include "bisturi/sim/tissue.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kRadius_m = 0.015;
const glm::dvec3 kCentre_m(0.0195, 0.0195, 0.0195);  // sphere(40, 15 mm)
const glm::dvec3 kFarAway_m(1.0, 1.0, 1.0);

/// The 15 mm sphere on its lowest 3 mm, stepped by a liver-like volume of 5 mm cells.
SimWorld resting_organ(bool sleeping) {
  WorldOptions options;
  options.integrator.sleeping = sleeping;
  SimWorld world(options);
  SoftBody body(testing::sphere(40, kRadius_m * 1e3), Material{});
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mesh().alive(v) && body.position(v).z < kCentre_m.z - kRadius_m + 0.003)
      body.set_anchored(v, true);
  }
  world.add_body(std::move(body));
  VolumeOptions volume;
  volume.cell_m = 0.005;
  volume.material = tissue_preset("liver").material;
  world.set_volume(0, volume);
  world.prepare();
  return world;
}

std::vector<glm::dvec3> alive_positions(const SoftBody& body) {
  std::vector<glm::dvec3> out;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
    if (body.mesh().alive(VertexId(i))) out.push_back(body.position(VertexId(i)));
  return out;
}

double largest_gap(const std::vector<glm::dvec3>& a, const std::vector<glm::dvec3>& b) {
  double gap = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    gap = std::max(gap, glm::length(a[i] - b[i]));
  return gap;
}

/// Steps with the probe away until the body sleeps; the steps it took (or `limit`).
int steps_to_sleep(SimWorld& world, int limit) {
  for (int s = 0; s < limit; ++s) {
    world.step(kFarAway_m);
    if (world.volume(0)->asleep()) return s + 1;
  }
  return limit;
}

TEST(SimVolumeSleep, ASettledOrganSleepsWhereItSettledAndSkipsItsSteps) {
  SimWorld sleeping = resting_organ(true);
  SimWorld awake = resting_organ(false);
  const int settle = steps_to_sleep(sleeping, 4000);
  ASSERT_LT(settle, 4000) << "the organ never fell asleep";
  for (int s = 0; s < settle; ++s)
    awake.step(kFarAway_m);
  // It sagged under its weight first (the test is not of a body that never moved).
  const SoftBody& body = sleeping.body(0);
  double sag = 0.0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
    if (body.mesh().alive(VertexId(i)))
      sag =
          std::max(sag, glm::length(body.position(VertexId(i)) - body.rest_position(VertexId(i))));
  EXPECT_GT(sag, 2e-4);
  const std::vector<glm::dvec3> asleep_at = alive_positions(body);
  for (int s = 0; s < 200; ++s) {
    sleeping.step(kFarAway_m);
    awake.step(kFarAway_m);
    EXPECT_TRUE(sleeping.volume(0)->asleep());
    EXPECT_EQ(sleeping.last_stats(0).awake_vertices, 0u);
    EXPECT_EQ(sleeping.last_stats(0).cg_iterations, 0);
  }
  // Still where it fell asleep, and where the organ kept awake is (within 20 um: the solver's
  // tolerance leaves that one creeping at under the sleep speed).
  EXPECT_EQ(largest_gap(alive_positions(body), asleep_at), 0.0);
  EXPECT_LT(largest_gap(alive_positions(body), alive_positions(awake.body(0))), 2e-5);
  EXPECT_GT(awake.last_stats(0).cg_iterations, 0);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.mesh().alive(VertexId(i))) {
      EXPECT_EQ(body.velocity(VertexId(i)), glm::dvec3(0.0));
    }
  }
}

TEST(SimVolumeSleep, AProbeWakesItInTheStepItTouchesAndPushesAsOnAnAwakeOrgan) {
  SimWorld sleeping = resting_organ(true);
  SimWorld awake = resting_organ(false);
  const int settle = steps_to_sleep(sleeping, 4000);
  ASSERT_LT(settle, 4000);
  for (int s = 0; s < settle; ++s)
    awake.step(kFarAway_m);
  // The tip 2 mm into the top of the settled organ.
  const double probe = sleeping.options().haptic.probe_radius_m;
  const glm::dvec3 tip = kCentre_m + glm::dvec3(0.0, 0.0, kRadius_m + probe - 0.002);
  const HapticOutput first = sleeping.step(tip);
  const HapticOutput first_awake = awake.step(tip);
  EXPECT_FALSE(sleeping.volume(0)->asleep());
  EXPECT_GT(sleeping.last_stats(0).awake_vertices, 0u);
  EXPECT_GT(sleeping.last_stats(0).cg_iterations, 0);
  ASSERT_TRUE(first.contact);
  EXPECT_NEAR(first.force_N.z, first_awake.force_N.z, 0.02 * std::abs(first_awake.force_N.z));
  // Pressed for a while, the two push back alike.
  HapticOutput last, last_awake;
  for (int s = 0; s < 300; ++s) {
    last = sleeping.step(tip);
    last_awake = awake.step(tip);
  }
  EXPECT_GT(last.force_N.z, 0.0);
  EXPECT_NEAR(last.force_N.z, last_awake.force_N.z, 0.02 * std::abs(last_awake.force_N.z));
  EXPECT_FALSE(sleeping.volume(0)->asleep());
  // Let go, it settles and sleeps again.
  EXPECT_LT(steps_to_sleep(sleeping, 4000), 4000);
}

TEST(SimVolumeSleep, AMovingSupportKeepsItAwakeAndSleepingOffNeverSleeps) {
  SimWorld breathing = resting_organ(true);
  SimWorld off = resting_organ(false);
  ASSERT_LT(steps_to_sleep(breathing, 4000), 4000);
  breathing.move_support(0, glm::dvec3(0.0, 0.0, 0.002));  // breathing in at 2 mm/s
  for (int s = 0; s < 300; ++s) {
    breathing.step(kFarAway_m);
    EXPECT_FALSE(breathing.volume(0)->asleep());
    EXPECT_GT(breathing.last_stats(0).awake_vertices, 0u);
  }
  EXPECT_EQ(steps_to_sleep(off, 3000), 3000);
}

}  // namespace
}  // namespace bisturi::sim
