// Two hands on one tissue (SessionSim with two HandSetups): each hand's probe acts in the same
// step, so what one hand does to the tissue the other feels, and one hand cuts while the other
// holds the tissue under tension.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <array>
#include <cmath>
#include <string>
#include <vector>

#include "arm_hand_setup.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/scene/dlfl_validate.h"
#include "haptic_rig.h"

namespace bisturi::runtime {
namespace {

using testing::at_mm;
using testing::kOrganTop_mm;

constexpr std::size_t kLeft = 0, kRight = 1;
constexpr std::uint32_t kGraspButton = 1u << 0, kCutButton = 1u << 1;

devices::HapticState hand_at(const glm::dvec3& tip_mm, std::uint32_t buttons = 0) {
  devices::HapticState s;
  s.end_effector_poses = {at_mm(tip_mm)};
  s.buttons = buttons;
  return s;
}

/// A point of the organ's top, `x_mm` along x from its pole, `inside_mm` under the surface.
glm::dvec3 on_top(double x_mm, double inside_mm) {
  const glm::dvec3 centre = kOrganTop_mm - glm::dvec3(0.0, 0.0, 28.0);
  const glm::dvec3 n = glm::normalize(glm::dvec3(x_mm, 0.0, std::sqrt(28.0 * 28.0 - x_mm * x_mm)));
  return centre + (28.0 - inside_mm) * n;
}

/// The phantom scene's organ (a solid: hexahedra under its surface, the liver preset) with two
/// arms.
SceneDescription two_arm_scene() {
  return parse_scene(R"(
[[solids]]
name = "organ"
phantom = "sphere"
dims = [44, 44, 44]
spacing_mm = 1.5
a_mm = 28.0
decimate = 0.12
smooth = 5
model = "volume"
cell_mm = 8.0

[solids.material]
preset = "liver"

[[solids.anchors]]
point_mm = [32.25, 32.25, 12.0]
normal = [0.0, 0.0, 1.0]
distance_mm = 0.0

[[devices]]
name = "left"
driver = "vendor-arm"
role = "haptic"
max_force_N = 2.0

[[devices]]
name = "right"
driver = "vendor-arm"
role = "haptic"
max_force_N = 2.0

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                     "two_arm_scene.toml");
}

struct TwoHands {
  SessionSim sim;
  std::array<devices::HapticState, 2> states;
  TwoHands()
      : sim(two_arm_scene(), build_solids(two_arm_scene()),
            std::vector<HandSetup>{testing::arm_hand_setup(2.0), testing::arm_hand_setup(2.0)}) {}
  const TickOutput& run(std::size_t ticks) {
    const TickOutput* out = nullptr;
    for (std::size_t i = 0; i < ticks; ++i)
      out = &sim.tick(states);
    return *out;
  }
};

double force_of(const TickOutput& out, std::size_t hand) {
  return glm::length(out.hand(hand).force_N);
}

TEST(TwoHands, WhatOneHandPullsTheOtherFeels) {
  // The right probe rests 2 mm into the organ's top; the left comes to the surface 9 mm away,
  // then either grasps it and lifts it 6 mm, or stays open where it is (the control).
  const glm::dvec3 right_tip = on_top(0.0, 2.0);
  const glm::dvec3 left_tip = on_top(-9.0, 1.0);
  std::array<double, 2> right_after{};
  for (const bool pull : {false, true}) {
    TwoHands h;
    // Both come down from 10 mm above over 200 ms (a probe must meet the surface from outside).
    for (int i = 0; i <= 200; ++i) {
      const glm::dvec3 above(0.0, 0.0, 10.0 * (1.0 - i / 200.0));
      h.states[kLeft] = hand_at(left_tip + above);
      h.states[kRight] = hand_at(right_tip + above);
      h.run(1);
    }
    const double right_before = force_of(h.run(300), kRight);
    ASSERT_GT(right_before, 0.02) << "the right probe presses the organ";
    if (pull) h.states[kLeft].buttons = kGraspButton;
    for (int i = 0; i <= 300; ++i) {
      if (pull)
        h.states[kLeft] = hand_at(left_tip + glm::dvec3(0.0, 0.0, 6.0 * i / 300.0), kGraspButton);
      h.run(1);
    }
    const TickOutput& out = h.run(300);
    EXPECT_EQ(out.hand(kLeft).grasping, pull);
    EXPECT_FALSE(out.hand(kRight).grasping);
    right_after[pull ? 1 : 0] = force_of(out, kRight);
    // The grasp is the left hand's: its events say so.
    bool left_grasped = false;
    for (const SessionEvent& e : h.sim.events()) {
      if (e.kind == SessionEventKind::GraspClosed) left_grasped = e.hand == kLeft && e.body == 0;
    }
    EXPECT_EQ(left_grasped, pull);
  }
  // Held still, the right hand's force stays; with the tissue lifted beside it, it grows (the
  // surface comes up against the probe).
  RecordProperty("right_N_left_still", std::to_string(right_after[0]));
  RecordProperty("right_N_left_pulling", std::to_string(right_after[1]));
  EXPECT_GT(right_after[1], right_after[0] * 1.2)
      << "without the pull " << right_after[0] << " N, with it " << right_after[1] << " N";
}

TEST(TwoHands, OneHandCutsWhileTheOtherHoldsTheTissue) {
  TwoHands h;
  const glm::dvec3 left_tip = on_top(-12.0, 1.0);
  h.states[kLeft] = hand_at(left_tip, kGraspButton);
  h.states[kRight] = hand_at(on_top(-4.0, 0.0) + glm::dvec3(0.0, 0.0, 10.0));
  h.run(10);
  // The left lifts the tissue 4 mm and holds it there.
  for (int i = 0; i <= 200; ++i)
    h.states[kLeft] = hand_at(left_tip + glm::dvec3(0.0, 0.0, 4.0 * i / 200.0), kGraspButton),
    h.run(1);
  ASSERT_TRUE(h.sim.grasping(kLeft));
  // The right's blade goes in 2 mm at x = -4 and sweeps to x = +8 with the cut button held.
  for (int i = 0; i <= 100; ++i) {
    h.states[kRight] = hand_at(on_top(-4.0, 2.0 * i / 100.0) + glm::dvec3(0.0, 0.0, 0.0));
    h.run(1);
  }
  for (int i = 0; i <= 300; ++i) {
    h.states[kRight] = hand_at(on_top(-4.0 + 12.0 * i / 300.0, 2.0), kCutButton);
    h.run(1);
  }
  h.states[kRight] = hand_at(on_top(8.0, 2.0));  // released: the cut is made
  const TickOutput& out = h.run(1);
  EXPECT_TRUE(out.topology_changed);
  const SessionEvent* cut = nullptr;
  for (const SessionEvent& e : h.sim.events()) {
    if (e.kind == SessionEventKind::Cut) cut = &e;
  }
  ASSERT_NE(cut, nullptr);
  EXPECT_EQ(cut->hand, kRight);
  EXPECT_NE(cut->detail.find("incision through"), std::string::npos) << cut->detail;
  // The left still holds the tissue after the cut (it took hold again where its jaws are), and
  // the solid is still valid.
  EXPECT_TRUE(h.sim.grasping(kLeft));
  EXPECT_TRUE(out.hand(kLeft).grasping);
  const ValidationReport valid = validate(h.sim.world().body(0).mesh());
  EXPECT_TRUE(valid.ok()) << valid.summary();
  h.run(100);
  EXPECT_EQ(h.sim.divergence_events(), 0u);
}

TEST(TwoHands, AStepTakesOneStatePerHand) {
  TwoHands h;
  const devices::HapticState one = hand_at(on_top(0.0, -5.0));
  EXPECT_THROW(h.sim.tick(one), std::invalid_argument);
  EXPECT_EQ(h.sim.hand_count(), 2u);
  EXPECT_EQ(h.sim.command_size(kRight), 3u);
}

}  // namespace
}  // namespace bisturi::runtime
