// Continuous collision of the haptic tip: a tip driven at 1 m/s (1 mm per 1 ms tick) through a
// thin slab and through a small sphere stays on the side it came from, its force
// always pushing back out; moving away is never held back. Each check also runs with the sweep
// off, where the same gesture tunnels: the checks would catch its loss.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kSpeed_m_per_tick = 0.001;  // 1 m/s at 1 kHz

/// A rigid world: every vertex anchored, no gravity, forces unclamped so the force's sign shows.
SimWorld rigid_world(SoftBody body, bool continuous) {
  WorldOptions options;
  options.haptic.max_force_N = 1e3;
  options.haptic.max_force_rate_N_per_s = 1e9;
  options.haptic.apply_reaction = false;
  options.haptic.continuous = continuous;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
    body.set_anchored(VertexId(i), true);
  world.add_body(std::move(body));
  return world;
}

/// A 20 x 20 mm slab `thickness_mm` thick, its top face at z = thickness.
SoftBody slab(double thickness_mm) {
  SoftBody body(build_oriented_manifold(cube_mesh(Dlfl::Vec3(0.0), 20.0)),
                testing::firm_material());
  for (auto& p : body.positions())
    p.z *= thickness_mm / 20.0;
  return body;
}

struct Gesture {
  int ticks_in_contact = 0;
  int ticks_pushed_through = 0;  ///< force pointing along the motion, into the far side
  int ticks_proxy_past_entry = 0;
  bool released = false;
};

/// The tip from `start` along `direction` at 1 m/s for `ticks`, then straight back out past the
/// start; entry_z: the height of the face it should stay above.
Gesture drive(SimWorld& world, const glm::dvec3& start, const glm::dvec3& direction, int ticks,
              double entry_z) {
  Gesture g;
  glm::dvec3 tip = start;
  for (int t = 0; t < ticks; ++t) {
    tip += kSpeed_m_per_tick * direction;
    const HapticOutput out = world.step(tip);
    if (!out.contact) continue;
    ++g.ticks_in_contact;
    if (glm::dot(out.force_N, direction) > 0.0) ++g.ticks_pushed_through;
    if (out.proxy_m.z < entry_z) ++g.ticks_proxy_past_entry;
  }
  HapticOutput out;
  for (int t = 0; t < ticks + 5; ++t) {
    tip -= kSpeed_m_per_tick * direction;
    out = world.step(tip);
  }
  g.released = !out.contact && glm::length(out.force_N) == 0.0;
  return g;
}

TEST(SimContinuousCollision, TipAtOneMetrePerSecondDoesNotTunnelThroughAThinSlab) {
  for (const double thickness_mm : {0.5, 1.0, 2.0}) {
    SimWorld world = rigid_world(slab(thickness_mm), true);
    const double top = thickness_mm * 1e-3;
    // Starting 2.7 mm above: the ticks land 0.3 mm past each millimetre, past any mid-plane.
    const Gesture g = drive(world, glm::dvec3(0.0101, 0.0099, top + 0.0027),
                            glm::dvec3(0, 0, -1), 10, top);
    EXPECT_GE(g.ticks_in_contact, 8) << thickness_mm;
    EXPECT_EQ(g.ticks_pushed_through, 0) << thickness_mm;
    EXPECT_EQ(g.ticks_proxy_past_entry, 0) << thickness_mm;
    EXPECT_TRUE(g.released) << thickness_mm;
  }
}

TEST(SimContinuousCollision, WithoutTheSweepTheSameGestureTunnels) {
  SimWorld world = rigid_world(slab(1.0), false);
  const Gesture g =
      drive(world, glm::dvec3(0.0101, 0.0099, 0.001 + 0.0027), glm::dvec3(0, 0, -1), 10, 0.001);
  EXPECT_GT(g.ticks_pushed_through + g.ticks_proxy_past_entry, 0);
}

TEST(SimContinuousCollision, TipDoesNotTunnelThroughASlantedSlab) {
  // A slanted path (1 m/s along it) also crosses in one tick.
  SimWorld world = rigid_world(slab(0.5), true);
  const glm::dvec3 dir = glm::normalize(glm::dvec3(0.6, 0.3, -1.0));
  const Gesture g = drive(world, glm::dvec3(0.006, 0.008, 0.0005 + 0.0021), dir, 8, 0.0005);
  EXPECT_GE(g.ticks_in_contact, 5);
  EXPECT_EQ(g.ticks_pushed_through, 0);
  EXPECT_EQ(g.ticks_proxy_past_entry, 0);
  EXPECT_TRUE(g.released);
}

TEST(SimContinuousCollision, TipThroughASmallSphereStaysOnTheEntrySide) {
  // sphere(24, 8 mm) shrunk to a 1 mm radius about its centre (a nodule, a vessel's width): the
  // tip, 0.3 mm above its top, lands 0.7 mm down, then 0.7 mm past the centre (where the closest
  // point is the bottom), then 0.7 mm below the sphere (where it touches nothing).
  constexpr double kCentre = 0.0115, kRadius = 0.001;
  const glm::dvec3 start(kCentre + 0.00003, kCentre - 0.00002, kCentre + kRadius + 0.0003);
  for (const bool continuous : {true, false}) {
    SoftBody body(testing::sphere(24, 8.0), testing::firm_material());
    for (auto& p : body.positions())
      p = glm::dvec3(kCentre) + (p - glm::dvec3(kCentre)) * (kRadius / 0.008);
    SimWorld world = rigid_world(std::move(body), continuous);
    // The proxy stays on the cap it entered: above the centre by half the radius.
    const Gesture g = drive(world, start, glm::dvec3(0, 0, -1), 3, kCentre + 0.5 * kRadius);
    if (continuous) {
      EXPECT_EQ(g.ticks_in_contact, 3);
      EXPECT_EQ(g.ticks_pushed_through, 0);
      EXPECT_EQ(g.ticks_proxy_past_entry, 0);
      EXPECT_TRUE(g.released);
    } else {
      EXPECT_GT(g.ticks_pushed_through + g.ticks_proxy_past_entry + (3 - g.ticks_in_contact), 0);
    }
  }
}

TEST(SimContinuousCollision, SlowPressMatchesTheClosestPointContact) {
  // A press at 0.05 m/s down to 0.75 mm into a 2 mm slab (short of its mid-plane, where the
  // closest point alone would flip): the sweep changes nothing, same forces either way.
  const glm::dvec3 top(0.0101, 0.0099, 0.002);
  SimWorld swept = rigid_world(slab(2.0), true);
  SimWorld plain = rigid_world(slab(2.0), false);
  glm::dvec3 tip = top + glm::dvec3(0, 0, 0.0005);
  int in_contact = 0;
  for (int t = 0; t < 25; ++t) {
    tip.z -= 0.00005;
    const HapticOutput a = swept.step(tip);
    const HapticOutput b = plain.step(tip);
    EXPECT_EQ(a.contact, b.contact) << t;
    in_contact += a.contact ? 1 : 0;
    EXPECT_NEAR(glm::length(a.force_N - b.force_N), 0.0, 1e-12) << t;
  }
  EXPECT_GE(in_contact, 10);
}

}  // namespace
}  // namespace bisturi::sim
