// A session's tissue as a volume (a solid's `model = "volume"`): the scene keys and their errors,
// and the liver scene's scripted procedure stepped at 500 Hz in virtual time (as the live
// session's tissue thread steps it on a 2-core machine): the liver is a volume and the vessel a
// membrane, the probe feels the liver, the cut goes through it, and the liver never rolls back.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <string>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/scene/dlfl_validate.h"

namespace bisturi::runtime {
namespace {

using devices::Nanoseconds;

std::string solid_with(const std::string& keys, const std::string& material) {
  return "[[solids]]\nname = 'organ'\nphantom = 'sphere'\n" + keys + "\n[solids.material]\n" +
         material + "\n";
}

TEST(SceneFile, ModelVolumeTakesACellSizeAndNeedsAnElasticMaterial) {
  const SceneDescription scene = parse_scene(
      solid_with("model = 'volume'\ncell_mm = 6.0", "preset = 'kidney'"), "scene.toml");
  EXPECT_EQ(scene.solids[0].model, SolidDescription::Model::Volume);
  EXPECT_DOUBLE_EQ(scene.solids[0].cell_mm, 6.0);
  EXPECT_EQ(parse_scene(solid_with("", "preset = 'liver'"), "scene.toml").solids[0].model,
            SolidDescription::Model::Surface);
  const auto error = [](const std::string& text) {
    try {
      (void)parse_scene(text, "scene.toml");
    } catch (const std::exception& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_NE(error(solid_with("model = 'volume'", "stiffness_N_per_m = 400.0")).find(
                "a volume takes its elasticity from the material"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'tetrahedra'", "preset = 'liver'")).find("not one of"),
            std::string::npos);
  EXPECT_NE(error(solid_with("cell_mm = 5.0", "preset = 'liver'")).find("only for model"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'volume'\ncell_mm = -1.0", "preset = 'liver'"))
                .find("cell_mm"),
            std::string::npos);
}

TEST(LiverScene, TheVolumeLiverFollowsTheScriptedProcedure) {
  const SceneDescription scene =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  ASSERT_EQ(scene.solids[0].model, SolidDescription::Model::Volume);
  const std::vector<BuiltSolid> solids = build_solids(scene);
  const Nanoseconds duration(static_cast<std::int64_t>(scene.duration_s * 1e9));
  const Procedure p =
      make_procedure("default", solids, duration, devices::SimulatedGlove::kJoints);
  std::vector<devices::ForceChannel> channels(5);
  for (devices::ForceChannel& c : channels)
    c.max_force_N = 3.0;
  SessionSim sim(scene, build_solids(scene), channels);
  ASSERT_NE(sim.world().volume(0), nullptr);
  EXPECT_EQ(sim.world().volume(1), nullptr);  // the vessel: an open tube, a membrane
  EXPECT_EQ(sim.world().volume(0)->embedded_vertices(), sim.world().body(0).mesh().num_vertices());

  double liver_force = 0.0;
  std::uint64_t liver_rollbacks = 0;
  const std::uint32_t ticks_per_step = 2;  // 500 Hz
  const std::int64_t steps = static_cast<std::int64_t>(scene.duration_s * 500.0);
  for (std::int64_t k = 1; k <= steps; ++k) {
    const Nanoseconds t(k * 2'000'000);
    devices::HapticState state;
    state.sample_time = t;
    state.end_effector_poses = {p.glove.pose_at(t)};
    state.finger_joint_angles_rad = p.glove.joints_at(t, devices::SimulatedGlove::kJoints);
    state.buttons = p.glove.buttons_at(t);
    const TickOutput& out = sim.tick(state, ticks_per_step);
    const sim::StepStats& liver = sim.world().last_stats(0);
    liver_rollbacks += liver.rolled_back ? 1 : 0;
    ASSERT_FALSE(liver.frozen) << "at " << k * 2 << " ms";
    if (out.contact && out.contact_stiffness_N_per_m < sim.world().options().haptic.coupling_N_per_m)
      liver_force = std::max(liver_force, glm::length(out.force_N));
  }
  EXPECT_EQ(liver_rollbacks, 0u);
  // The palpation pressed the liver (a contact whose stiffness is the volume's, in series with
  // the coupling), and the cut went through its surface.
  EXPECT_GT(liver_force, 0.05);
  bool cut_liver = false;
  for (const SessionEvent& e : sim.events())
    cut_liver = cut_liver || (e.kind == SessionEventKind::Cut && e.body == 0);
  EXPECT_TRUE(cut_liver);
  EXPECT_TRUE(validate(sim.world().body(0).mesh()).ok());
  EXPECT_EQ(sim.world().volume(0)->embedded_vertices(), sim.world().body(0).mesh().num_vertices());
}

}  // namespace
}  // namespace bisturi::runtime
