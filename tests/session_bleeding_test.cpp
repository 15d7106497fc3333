// Bleeding in the session's simulation: a cut across a pulsing vessel's wall opens it, blood
// leaves at the flow its pressure drives and is accounted for particle by particle, a grasper
// holding the vessel stops the flow, and none of it ends a step inside the tissue.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>

#include <string>
#include <vector>

#include "arm_hand_setup.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/sim/units.h"

namespace bisturi::runtime {
namespace {

constexpr std::size_t kLeft = 0, kRight = 1, kVessel = 1;  // the glove is the left hand here
constexpr std::uint64_t kGrasp = 1u << 0, kCut = 1u << 1;

/// The instrument at p_mm, its blade (the pose's +z) pointing along `blade`, buttons held.
devices::HapticState hand_at(const glm::dvec3& p_mm, std::uint64_t buttons = 0,
                             const glm::dvec3& blade = {0.0, 0.0, 1.0}) {
  devices::HapticState s;
  s.end_effector_poses.resize(1);
  const glm::dvec3 m = sim::scene_to_sim(p_mm);
  s.end_effector_poses[0].position_m = {m.x, m.y, m.z};
  const glm::dquat q = glm::rotation(glm::dvec3(0.0, 0.0, 1.0), glm::normalize(blade));
  s.end_effector_poses[0].orientation = {q.w, q.x, q.y, q.z};
  s.buttons = buttons;
  return s;
}

/// config/bleeding.toml (its vessel pulsing, the procedure's cut across the vessel) with two
/// hands: the scripted glove (button 0 cuts, its fingers grasp) and an arm (grasp, cut).
struct Field {
  SceneDescription scene = read_scene_file(BISTURI_SOURCE_DIR "/config/bleeding.toml");
  SessionSim sim{scene, build_solids(scene),
                 std::vector<HandSetup>{HandSetup{}, testing::arm_hand_setup(3.0)}};
  std::array<devices::HapticState, 2> hands{hand_at({20.0, -20.0, 90.0}),
                                            hand_at({100.0, -20.0, 90.0})};
  bool accounted = true;
  void run(int ticks) {
    for (int k = 0; k < ticks; ++k) {
      (void)sim.tick(hands);
      const sim::BloodCounts& c = sim.blood().counts();
      accounted = accounted && c.emitted == c.in_flight + c.pooled + c.drained;
    }
  }
  /// The vessel's anterior wall (its most -y vertex) at height z_mm.
  glm::dvec3 wall_at(double z_mm) {
    const sim::SoftBody& vessel = sim.world().body(kVessel);
    glm::dvec3 best(0.0, 1e9, 0.0);
    for (const glm::dvec3& p : vessel.positions()) {
      const glm::dvec3 mm = sim::sim_to_scene(p);
      if (std::abs(mm.z - z_mm) < 3.0 && mm.y < best.y) best = mm;
    }
    return best;
  }
};

constexpr double kProcedure_s = 6.0;

TEST(Bleeding, ACutVesselBleedsUntilAGrasperClampsIt) {
  Field f;
  // The glove follows the scene's procedure to just after its cut across the vessel (at 0.905
  // of it), the arm held away.
  const Procedure procedure =
      make_procedure("default", build_solids(f.scene),
                     std::chrono::milliseconds(static_cast<int>(kProcedure_s * 1000.0)),
                     devices::SimulatedGlove::kJoints);
  const auto cut_done = static_cast<int>(0.92 * kProcedure_s * 1000.0);
  for (int k = 1; k <= cut_done; ++k) {
    const devices::Nanoseconds t = std::chrono::milliseconds(k);
    devices::HapticState& glove = f.hands[kLeft];
    glove.end_effector_poses.assign(1, procedure.glove.pose_at(t));
    glove.finger_joint_angles_rad = procedure.glove.joints_at(t, devices::SimulatedGlove::kJoints);
    glove.buttons = procedure.glove.buttons_at(t);
    f.run(1);
  }
  const SessionEvent* cut = nullptr;
  for (const SessionEvent& e : f.sim.events())
    if (e.kind == SessionEventKind::Cut) cut = &e;
  ASSERT_NE(cut, nullptr);
  ASSERT_EQ(cut->body, static_cast<std::int32_t>(kVessel));
  ASSERT_NE(cut->detail.find("incision through"), std::string::npos) << cut->detail;
  // It bleeds, at a flow its pulse drives.
  f.run(600);
  const std::uint64_t bled = f.sim.blood().counts().emitted;
  EXPECT_GT(bled, 50u);
  EXPECT_GT(f.sim.blood_flow_m3_s(), 0.0);
  // The arm clamps the vessel below the cut: no more blood leaves it.
  const glm::dvec3 out(0.0, -1.0, 0.0);
  const glm::dvec3 below = f.wall_at(22.0);
  for (int i = 0; i <= 200; ++i) {
    f.hands[kRight] = hand_at(below + (10.0 - 11.0 * i / 200.0) * out);
    f.run(1);
  }
  f.hands[kRight] = hand_at(below - 1.0 * out, kGrasp);
  f.run(20);
  ASSERT_TRUE(f.sim.grasping(kRight));
  const std::uint64_t clamped_at = f.sim.blood().counts().emitted;
  f.run(500);
  EXPECT_EQ(f.sim.blood().counts().emitted, clamped_at) << "clamped: no flow";
  EXPECT_EQ(f.sim.blood_flow_m3_s(), 0.0);
  EXPECT_TRUE(f.accounted) << "emitted = in flight + pooled + drained, every step";
  EXPECT_GT(f.sim.blood().counts().pooled, 0u) << "some came to rest";
  // None inside the tissue at the end.
  for (const glm::dvec3& p : f.sim.blood().positions()) {
    for (std::uint32_t b = 0; b < f.sim.body_count(); ++b) {
      const sim::SurfacePoint q =
          f.sim.world().bvh(b).closest_point(f.sim.world().body(b), p, 0.006);
      if (q.found) {
        EXPECT_GE(glm::dot(p - q.point_m, q.normal), -1e-9);
      }
    }
  }
  // Released, it bleeds again.
  f.hands[kRight] = hand_at(below + 10.0 * out);
  f.run(300);
  EXPECT_GT(f.sim.blood().counts().emitted, clamped_at);
}

TEST(Bleeding, AnOrganCutDoesNotBleed) {
  // The default scene's scripted cut goes across the organ, which has no pulse: no blood.
  const SceneDescription scene = default_scene();
  SessionSim sim(scene, build_solids(scene), std::vector<HandSetup>{testing::arm_hand_setup(3.0)});
  const glm::dvec3 top(32.25, 32.25, 60.25);
  for (int i = 0; i <= 200; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(-8.0, 0.0, 10.0 - 13.0 * i / 200.0)));
  for (int i = 0; i <= 300; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(-8.0 + 16.0 * i / 300.0, 0.0, -3.0), kCut));
  for (int i = 0; i < 300; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(0.0, 0.0, 30.0)));
  EXPECT_EQ(sim.blood().counts().emitted, 0u);
}

}  // namespace
}  // namespace bisturi::runtime
