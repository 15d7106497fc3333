// Bleeding in the session's simulation: a cut across a pulsing vessel's wall opens it, blood
// leaves at the flow its pressure drives and is accounted for particle by particle, a grasper
// holding the vessel stops the flow, and none of it ends a step inside the tissue.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>

#include <algorithm>
#include <array>
#include <fstream>
#include <sstream>
#include <string>
#include <utility>
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
  explicit Field(SceneDescription s = read_scene_file(BISTURI_SOURCE_DIR "/config/bleeding.toml"))
      : scene(std::move(s)) {}
  SceneDescription scene;
  SessionSim sim{scene, build_solids(scene),
                 std::vector<HandSetup>{HandSetup{}, testing::arm_hand_setup(3.0)}};
  std::array<devices::HapticState, 2> hands{hand_at({20.0, -20.0, 90.0}),
                                            hand_at({100.0, -20.0, 90.0})};
  bool accounted = true;
  /// Whether run() waits for the blood's thread after every tick (to check the accounts).
  bool settle_each_tick = true;
  bool blood_held = false;  ///< the blood's clock held over the ticks run()
  void run(int ticks) {
    for (int k = 0; k < ticks; ++k) {
      (void)sim.tick(hands, 1, blood_held);
      if (!settle_each_tick) continue;
      const sim::BloodCounts& c = sim.blood().counts();
      accounted = accounted && c.emitted == c.in_flight + c.pooled + c.drained + c.recycled;
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

/// The glove follows the scene's procedure to just after its cut across the vessel (at 0.905
/// of it), the arm held away.
void cut_the_vessel(Field& f) {
  const Procedure procedure =
      make_procedure("default", build_solids(f.scene),
                     std::chrono::milliseconds(static_cast<int>(kProcedure_s * 1000.0)),
                     devices::SimulatedGlove::kJoints);
  const auto cut_done = static_cast<int>(0.92 * kProcedure_s * 1000.0);
  for (int k = 1; k <= cut_done; ++k) {
    const devices::Nanoseconds t = std::chrono::milliseconds(k);
    devices::HapticState& glove = f.hands[kLeft];
    glove.end_effector_poses.assign(1, procedure.first_hand.pose_at(t));
    glove.finger_joint_angles_rad =
        procedure.first_hand.joints_at(t, devices::SimulatedGlove::kJoints);
    glove.buttons = procedure.first_hand.buttons_at(t);
    f.run(1);
  }
}

TEST(Bleeding, ACutVesselBleedsUntilAGrasperClampsIt) {
  Field f;
  cut_the_vessel(f);
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
  EXPECT_TRUE(f.accounted) << "emitted = in flight + pooled + drained + recycled, every step";
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

TEST(Bleeding, TheBloodsThreadBleedsTheSameWhenItFallsBehind) {
  // In one run the tissue waits for every blood step; in the other it never does until the
  // end, and the blood's thread falls as far behind as it may: the same blood, bit for bit.
  Field waited, free;
  free.settle_each_tick = false;
  cut_the_vessel(waited);
  cut_the_vessel(free);
  waited.run(1500);
  free.run(1500);
  const std::vector<glm::dvec3> a = waited.sim.blood().positions();
  const std::vector<glm::dvec3> b = free.sim.blood().positions();
  ASSERT_GT(a.size(), 50u);
  EXPECT_EQ(a, b);
  EXPECT_EQ(waited.sim.state_hash(), free.sim.state_hash());
  EXPECT_EQ(waited.sim.blood_step_ms().size(), free.sim.blood_step_ms().size());
}

TEST(Bleeding, WhileItsClockIsHeldTheBloodStandsStillAndResumesWhereItStopped) {
  // What a session does when the blood's thread falls behind: the tissue goes on, the blood's
  // time stands still (nothing emitted, nothing moves), and it goes on from there after.
  Field f;
  cut_the_vessel(f);
  f.run(200);
  const sim::BloodCounts before = f.sim.blood().counts();
  const std::vector<glm::dvec3> still = f.sim.blood().positions();
  ASSERT_GT(before.emitted, 20u);
  f.blood_held = true;
  f.run(250);
  EXPECT_EQ(f.sim.blood().counts().emitted, before.emitted);
  EXPECT_EQ(f.sim.blood().positions(), still);
  EXPECT_NEAR(f.sim.blood_held_s(), 0.25, 1e-9);
  f.blood_held = false;
  f.run(100);
  EXPECT_GT(f.sim.blood().counts().emitted, before.emitted);
  EXPECT_NE(f.sim.blood().positions(), still);
  EXPECT_NEAR(f.sim.blood_held_s(), 0.25, 1e-9);
  // The same holds at the same steps bleed the same, bit for bit (what the replay relies on).
  Field again;
  cut_the_vessel(again);
  again.run(200);
  again.blood_held = true;
  again.run(250);
  again.blood_held = false;
  again.run(100);
  EXPECT_EQ(again.sim.blood().positions(), f.sim.blood().positions());
  EXPECT_EQ(again.sim.state_hash(), f.sim.state_hash());
}

TEST(Bleeding, AnArterySpurtsWithTheBeatAndAVeinOozesSteadily) {
  // The bleeding scene's vessel as it is (80/120 mmHg) and as a vein (a steady 10 mmHg): the
  // flow through the same cut over the next 1.5 s.
  std::ifstream file(BISTURI_SOURCE_DIR "/config/bleeding.toml");
  std::stringstream text;
  text << file.rdbuf();
  std::string vein = text.str();
  const std::string pulse = "pulse_mmHg = [80.0, 120.0]";
  ASSERT_NE(vein.find(pulse), std::string::npos);
  vein.replace(vein.find(pulse), pulse.size(), "pressure_mmHg = 10.0");
  std::array<double, 2> least{1e9, 1e9}, most{0.0, 0.0}, mean{0.0, 0.0};
  for (const bool is_vein : {false, true}) {
    Field f(is_vein ? parse_scene(vein, "vein.toml", BISTURI_SOURCE_DIR "/config")
                    : read_scene_file(BISTURI_SOURCE_DIR "/config/bleeding.toml"));
    cut_the_vessel(f);
    const std::size_t k = is_vein ? 1 : 0;
    for (int blood_step = 0; blood_step < 135; ++blood_step) {
      f.run(11);  // about one blood step (1/90 s)
      least[k] = std::min(least[k], f.sim.blood_flow_m3_s());
      most[k] = std::max(most[k], f.sim.blood_flow_m3_s());
      mean[k] += f.sim.blood_flow_m3_s() / 135.0;
    }
  }
  for (const std::size_t k : {0u, 1u})
    RecordProperty(k == 0 ? "artery_ml_per_s" : "vein_ml_per_s",
                   std::to_string(least[k] * 1e6) + " to " + std::to_string(most[k] * 1e6));
  EXPECT_GT(least[0], 0.0);
  EXPECT_GT(most[0], 1.1 * least[0]) << "the artery's flow follows the beat";
  EXPECT_GT(least[1], 0.0);
  EXPECT_DOUBLE_EQ(most[1], least[1]) << "the vein's is steady";
  EXPECT_LT(mean[1], 0.5 * mean[0]) << "and slower";
}

TEST(SceneFile, AVeinHasAPressureAndNoPulse) {
  const auto vessel = [](const std::string& keys) {
    return "[[solids]]\nname = 'vein'\nphantom = 'tube'\n" + keys +
           "\n[solids.material]\nstiffness_N_per_m = 900.0\n";
  };
  const SceneDescription vein = parse_scene(vessel("pressure_mmHg = 8.0"), "scene.toml");
  ASSERT_TRUE(vein.solids[0].pulse_mmHg.has_value());
  EXPECT_EQ(*vein.solids[0].pulse_mmHg, (std::array<double, 2>{8.0, 8.0}));
  const auto error = [&](const std::string& keys) {
    try {
      (void)parse_scene(vessel(keys), "scene.toml");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error("pressure_mmHg = 8.0\npulse_mmHg = [80.0, 120.0]").find("not both"),
            std::string::npos);
  EXPECT_NE(error("pressure_mmHg = 0.0").find("pressure_mmHg"), std::string::npos);
  EXPECT_NE(error("pressure_mmHg = 8.0\nsimulate = false").find("no lumen"), std::string::npos);
}

TEST(Bleeding, AnOrganCutDoesNotBleed) {
  // The phantom scene's scripted cut goes across the organ, which has no lumen: no blood.
  const SceneDescription scene = read_scene_file(BISTURI_SOURCE_DIR "/config/phantom.toml");
  SessionSim sim(scene, build_solids(scene), std::vector<HandSetup>{testing::arm_hand_setup(3.0)});
  const glm::dvec3 top(32.25, 32.25, 60.25);
  for (int i = 0; i <= 200; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(-8.0, 0.0, 10.0 - 13.0 * i / 200.0)));
  for (int i = 0; i <= 300; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(-8.0 + 16.0 * i / 300.0, 0.0, -3.0), kCut));
  for (int i = 0; i < 300; ++i)
    (void)sim.tick(hand_at(top + glm::dvec3(0.0, 0.0, 30.0)));
  bool cut = false;
  for (const SessionEvent& e : sim.events())
    cut = cut ||
          (e.kind == SessionEventKind::Cut && e.body == 0 && e.detail.rfind("incision", 0) == 0);
  EXPECT_TRUE(cut);
  EXPECT_EQ(sim.blood().counts().emitted, 0u);
}

}  // namespace
}  // namespace bisturi::runtime
