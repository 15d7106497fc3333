// A session's tissue as a volume (a solid's `model = "volume"`): the scene keys and their errors,
// and the liver scene's scripted procedure stepped at 500 Hz in virtual time (as the live
// session's tissue thread steps it on a 2-core machine): the liver is a volume and the vessel a
// membrane, the probe feels the liver, the cut goes through it, and the liver never rolls back.

#include <gtest/gtest.h>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/volume/hex_lattice.h"
#include "liver_procedure.h"

namespace bisturi::runtime {
namespace {

using devices::Nanoseconds;

std::string solid_with(const std::string& keys, const std::string& material) {
  return "[[solids]]\nname = 'organ'\nphantom = 'sphere'\n" + keys + "\n[solids.material]\n" +
         material + "\n";
}

/// The error parsing `text` gives, or "no error".
std::string error(const std::string& text) {
  try {
    (void)parse_scene(text, "scene.toml");
  } catch (const std::exception& e) {
    return std::string(e.what());
  }
  return std::string("no error");
}

TEST(SceneFile, ModelVolumeTakesACellSizeAndNeedsAnElasticMaterial) {
  const SceneDescription scene =
      parse_scene(solid_with("model = 'volume'\ncell_mm = 6.0", "preset = 'kidney'"), "scene.toml");
  EXPECT_EQ(scene.solids[0].model, SolidDescription::Model::Volume);
  EXPECT_DOUBLE_EQ(scene.solids[0].cell_mm, 6.0);
  // Without `model`: a volume when the material has a modulus, a membrane for springs by hand.
  EXPECT_EQ(parse_scene(solid_with("", "preset = 'liver'"), "scene.toml").solids[0].model,
            SolidDescription::Model::Volume);
  EXPECT_EQ(parse_scene(solid_with("", "stiffness_N_per_m = 400.0"), "scene.toml").solids[0].model,
            SolidDescription::Model::Surface);
  EXPECT_NE(error(solid_with("model = 'volume'", "stiffness_N_per_m = 400.0"))
                .find("a volume takes its elasticity from the material"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'tetrahedra'", "preset = 'liver'")).find("not one of"),
            std::string::npos);
  EXPECT_NE(error(solid_with("cell_mm = 5.0", "stiffness_N_per_m = 400.0")).find("only for model"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'surface'\ncell_mm = 5.0", "preset = 'liver'"))
                .find("only for model"),
            std::string::npos);
  EXPECT_NE(
      error(solid_with("model = 'volume'\ncell_mm = -1.0", "preset = 'liver'")).find("cell_mm"),
      std::string::npos);
  // The cells along a cut split before they part: 1 (not at all) to 4 times finer.
  EXPECT_EQ(
      parse_scene(solid_with("model = 'volume'\ncut_refine = 3", "preset = 'liver'"), "scene.toml")
          .solids[0]
          .cut_refine,
      3);
  EXPECT_NE(
      error(solid_with("model = 'volume'\ncut_refine = 5", "preset = 'liver'")).find("cut_refine"),
      std::string::npos);
  EXPECT_NE(error(solid_with("model = 'surface'\ncut_refine = 2", "preset = 'liver'"))
                .find("only for model"),
            std::string::npos);
}

TEST(SceneFile, AClosedSolidWithAModulusIsAVolumeAndAnOpenOneAMembrane) {
  // Neither names a model: the sphere becomes a volume; the tube, open at its ends, cannot hold
  // one and stays a membrane (given model = "volume", it is an error).
  const std::string tube =
      "[[solids]]\nname = 'tube'\nphantom = 'tube'\ndims = [24, 24, 40]\n"
      "spacing_mm = 1.0\na_mm = 6.0\n[solids.material]\npreset = 'vessel-wall'\n";
  const SceneDescription scene =
      parse_scene(solid_with("", "preset = 'liver'") + tube, "scene.toml");
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  EXPECT_NE(sim.world().volume(0), nullptr);
  EXPECT_EQ(sim.world().volume(1), nullptr);
  const SceneDescription asked = parse_scene(
      solid_with("", "preset = 'liver'") +
          "[[solids]]\nname = 'tube'\nphantom = 'tube'\ndims = [24, 24, 40]\nspacing_mm = 1.0\n"
          "a_mm = 6.0\nmodel = 'volume'\n[solids.material]\npreset = 'vessel-wall'\n",
      "scene.toml");
  EXPECT_THROW(SessionSim(asked, build_solids(asked), std::vector<devices::ForceChannel>{}),
               std::exception);
}

TEST(LiverScene, TheVolumeLiverFollowsTheScriptedProcedure) {
  LiverProcedure liver_scene;
  ASSERT_EQ(liver_scene.scene.solids[0].model, SolidDescription::Model::Volume);
  SessionSim& sim = liver_scene.sim;
  ASSERT_NE(sim.world().volume(0), nullptr);
  EXPECT_EQ(sim.world().volume(1), nullptr);  // the vessel: an open tube, a membrane
  EXPECT_EQ(sim.world().volume(0)->embedded_vertices(), sim.world().body(0).mesh().num_vertices());

  double top_at_rest = -1e9;
  for (const glm::dvec3& x : sim.world().body(0).positions())
    top_at_rest = std::max(top_at_rest, x.z);
  double palpation_force = 0.0;
  std::uint64_t liver_rollbacks = 0;
  for (std::int64_t k = 1; k <= liver_scene.steps(); ++k) {
    const TickOutput& out = liver_scene.step(k);
    const sim::StepStats& liver = sim.world().last_stats(0);
    liver_rollbacks += liver.rolled_back ? 1 : 0;
    ASSERT_FALSE(liver.frozen) << "at " << k * 2 << " ms";
    // The palpation (1.2 to 2.6 s) presses the liver: a contact whose stiffness is the volume's,
    // in series with the coupling.
    const bool palpating = k >= 600 && k <= 1300;
    if (palpating && out.contact &&
        out.contact_stiffness_N_per_m < sim.world().options().haptic.coupling_N_per_m)
      palpation_force = std::max(palpation_force, glm::length(out.force_N));
    if (k == 550) {  // 1.1 s, before the first touch: its weight is carried, so it has not sagged
      double top = -1e9;
      for (const glm::dvec3& x : sim.world().body(0).positions())
        top = std::max(top, x.z);
      EXPECT_NEAR(top, top_at_rest, 0.0002);
    }
  }
  EXPECT_EQ(liver_rollbacks, 0u);
  EXPECT_GT(palpation_force, 0.05);
  // The blade went through the liver's face and the artery's back wall: both are cut, and the
  // artery, pulsing, bleeds.
  std::vector<std::int32_t> cut_bodies;
  for (const SessionEvent& e : sim.events())
    if (e.kind == SessionEventKind::Cut && e.detail.rfind("incision", 0) == 0)
      cut_bodies.push_back(e.body);
  EXPECT_EQ(cut_bodies, (std::vector<std::int32_t>{0, 1}));
  EXPECT_GT(sim.blood().counts().emitted, 0u);
  EXPECT_TRUE(validate(sim.world().body(0).mesh()).ok());
  EXPECT_TRUE(validate(sim.world().body(1).mesh()).ok());
  EXPECT_EQ(sim.world().volume(0)->embedded_vertices(), sim.world().body(0).mesh().num_vertices());
}

TEST(LiverScene, ACutRoundTheArteryFollowsTheBlade) {
  // The decimated tube's triangles run in long strips along its axis: from a vertex on its side
  // none is nearer a blade going round its back wall. The cut goes round to the vertex nearest
  // each blade point instead of stopping after one edge (it stopped there before).
  const SceneDescription scene =
      read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  sim::SoftBody& artery = sim.world().body(1);
  // Its back wall at z 135 mm, from one side round to the other (axis x 135.3, y 0.9, 6 mm).
  std::vector<glm::dvec3> blade;
  for (int i = 0; i <= 60; ++i) {
    const double a = 3.141592653589793 * (1.0 - i / 60.0);
    blade.push_back(sim::scene_to_sim({135.3 + 6.0 * std::cos(a), 0.9 + 6.0 * std::sin(a), 135.0}));
  }
  const sim::CutResult cut = sim::cut_surface(artery, blade);
  EXPECT_GE(cut.path.size(), 5u);
  EXPECT_TRUE(validate(artery.mesh()).ok());
}

TEST(SceneFile, RefineSplitsTheVolumesCellsInABox) {
  // The phantom sphere's middle, from a build without the refinement.
  const SceneDescription plain =
      parse_scene(solid_with("model = 'volume'\ncell_mm = 8.0", "preset = 'liver'"), "scene.toml");
  const std::vector<BuiltSolid> built = build_solids(plain);
  glm::dvec3 lo(1e9), hi(-1e9);
  for (const glm::dvec3& p : built[0].mesh.positions()) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  const glm::dvec3 middle = 0.5 * (lo + hi);
  const std::string refine = "model = 'volume'\ncell_mm = 8.0\n[solids.refine]\ncentre_mm = [" +
                             std::to_string(middle.x) + ", " + std::to_string(middle.y) + ", " +
                             std::to_string(middle.z) + "]\n";
  const SceneDescription scene = parse_scene(
      solid_with(refine + "factor = 4\nhalf_width_mm = 6.0\nfollow = true", "preset = 'liver'"),
      "scene.toml");
  ASSERT_TRUE(scene.solids[0].refine.has_value());
  EXPECT_EQ(scene.solids[0].refine->factor, 4);
  EXPECT_DOUBLE_EQ(scene.solids[0].refine->half_width_mm, 6.0);
  EXPECT_TRUE(scene.solids[0].refine->follow);
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  SessionSim coarse(plain, build_solids(plain), std::vector<devices::ForceChannel>{});
  const sim::HexLattice& lattice = sim.world().volume(0)->volume().lattice();
  EXPECT_FALSE(lattice.hanging.empty());
  EXPECT_GT(lattice.cells.size(), coarse.world().volume(0)->volume().lattice().cells.size());
  EXPECT_NEAR(sim.world().volume(0)->volume().finest_cell_m(), 0.002, 1e-9);
  EXPECT_TRUE(sim.world().volume(0)->options().refine_follows);
  // Twice the cell by default; the factor 2 to 4; for volumes only; a centre it must have.
  EXPECT_DOUBLE_EQ(parse_scene(solid_with(refine, "preset = 'liver'"), "scene.toml")
                       .solids[0]
                       .refine->half_width_mm,
                   16.0);
  EXPECT_NE(error(solid_with(refine + "factor = 5", "preset = 'liver'")).find("factor"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'surface'\n[solids.refine]\ncentre_mm = [0.0, 0.0, 0.0]",
                             "preset = 'liver'"))
                .find("only for model"),
            std::string::npos);
  EXPECT_NE(error(solid_with("model = 'volume'\n[solids.refine]\nfactor = 2", "preset = 'liver'"))
                .find("needs centre_mm"),
            std::string::npos);
}

TEST(SceneFile, SupportedIsForVolumesOnly) {
  EXPECT_TRUE(parse_scene(solid_with("model = 'volume'\nsupported = true", "preset = 'liver'"),
                          "scene.toml")
                  .solids[0]
                  .supported);
  EXPECT_NE(error(solid_with("model = 'surface'\nsupported = true", "preset = 'liver'"))
                .find("only for model"),
            std::string::npos);
}

TEST(SceneFile, DrawnIsForVolumesAndDownsamplesLabelMapsOnly) {
  const SceneDescription scene = parse_scene(
      solid_with("decimate = 0.2\n[solids.drawn]\ndecimate = 0.8\nsmooth = 2", "preset = 'liver'"),
      "scene.toml");
  ASSERT_TRUE(scene.solids[0].drawn.has_value());
  EXPECT_DOUBLE_EQ(scene.solids[0].drawn->decimate, 0.8);
  EXPECT_EQ(scene.solids[0].drawn->smooth, 2);
  EXPECT_NE(
      error(solid_with("model = 'surface'\n[solids.drawn]\ndecimate = 0.8", "preset = 'liver'"))
          .find("only for model"),
      std::string::npos);
  EXPECT_NE(error(solid_with("[solids.drawn]\ndownsample = [2, 2, 2]", "preset = 'liver'"))
                .find("label map"),
            std::string::npos);
  EXPECT_NE(error(solid_with("[solids.drawn]\ndecimate = 1.5", "preset = 'liver'")).find("(0, 1]"),
            std::string::npos);
  EXPECT_NE(error(solid_with("[solids.drawn]\nlevel = 2", "preset = 'liver'")).find("level"),
            std::string::npos);
}

TEST(SceneFile, InnerStructuresAreShapesInsideAVolume) {
  const std::string lesion =
      "[[solids.inner]]\nname = 'lesion'\nphantom = 'sphere'\na_mm = 3.0\ncolour = [0.9, 0.8, "
      "0.5]\n";
  const SceneDescription scene = parse_scene(solid_with(lesion, "preset = 'liver'"), "scene.toml");
  ASSERT_EQ(scene.solids[0].inner.size(), 1u);
  EXPECT_EQ(scene.solids[0].inner[0].name, "lesion");
  EXPECT_FALSE(scene.solids[0].inner[0].simulate);
  EXPECT_DOUBLE_EQ(scene.solids[0].inner[0].material.colour[0], 0.9);
  EXPECT_NE(
      error(solid_with("model = 'surface'\n" + lesion, "preset = 'liver'")).find("only for model"),
      std::string::npos);
  EXPECT_NE(error(solid_with(lesion + "anchors = []\n", "preset = 'liver'")).find("anchors"),
            std::string::npos);
}

}  // namespace
}  // namespace bisturi::runtime
