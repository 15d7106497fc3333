// The liver scene's scripted cut seen in the frame (lavapipe or a GPU): the drawn liver, riding
// on its volume, before the cut, 50 ms after it and a second later, from in front of the cut.
// The view changes along the cut's projected path, the change shows the interior colour, and
// the interior shown grows over the second as the wound opens under the liver's tension.
// BISTURI_DUMP_WOUND=DIR writes the left eye's three frames there (before.png, early.png,
// late.png).

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/units.h"
#include "liver_procedure.h"
#include "render_test_support.h"
#include "session/drawn_surface.h"

namespace bisturi::render {
namespace {

using testing::Capture;
using testing::RendererFixture;

constexpr std::uint32_t kSize = 256;

/// 70 mm in front of the cut's middle, looking at it along +y, z up.
HeadPose facing_the_cut() {
  HeadPose pose;
  pose.position_mm = glm::dvec3(135.0, -44.0, 135.0);
  pose.orientation = glm::angleAxis(glm::radians(90.0), glm::dvec3(1.0, 0.0, 0.0));
  pose.sample_time = PoseClock::now();
  return pose;
}

/// The interior colour (0.42, 0.06, 0.05 linear) lit and in sRGB: green and blue about 0.4 of
/// red. The liver's outside (0.80, 0.36, 0.30) keeps green at 0.7 of red.
bool interior_hue(const std::uint8_t* px) {
  return px[0] > 20 && px[1] < 0.5 * px[0] && px[2] < 0.5 * px[0];
}

class RenderLiverWoundTest : public RendererFixture {};

TEST_F(RenderLiverWoundTest, TheScriptedCutOpensInTheInteriorColourAlongItsPathAndWidens) {
  RendererOptions options;
  options.level_of_detail = false;  // the same level throughout: differences are the cut's
  options.levels.derived_levels = false;
  options.clear_colour = glm::vec3(0.0f);
  auto* r = make(options, kSize);
  REQUIRE_RENDERER(r);

  runtime::LiverProcedure liver;
  runtime::SessionSim& sim = liver.sim;
  const sim::VolumeBody* volume = sim.world().volume(0);
  ASSERT_NE(volume, nullptr);
  runtime::DrawnSurface drawn(*runtime::build_drawn_surface(liver.scene.solids[0], "liver.toml"),
                              &sim.world().body(0),
                              std::make_shared<const sim::HexLattice>(volume->volume().lattice()));
  const auto follow = [&] {
    const auto x = volume->volume().positions();
    drawn.follow(std::vector<glm::dvec3>(x.begin(), x.end()));
  };
  Material liver_material;
  const auto& c = liver.scene.solids[0].material.colour;
  liver_material.colour = glm::vec3(c[0], c[1], c[2]);
  const SolidId id = r->add_solid(drawn.mesh(), liver_material);
  const auto capture = [&](Capture& into) {
    r->set_sink(&into);
    r->render(facing_the_cut());
    r->flush();
  };

  // Just before the cut.
  std::int64_t k = 1;
  for (; sim.incisions().empty(); ++k) {
    const runtime::TickOutput& out = liver.step(k);
    (void)out;
    if (sim.incisions().empty() && k % 25 == 0) {
      follow();
      r->update_solid(id, drawn.mesh());
    }
  }
  Capture before, early, late;
  follow();
  r->update_solid(id, drawn.mesh());
  capture(before);
  drawn.use_lattice(std::make_shared<const sim::HexLattice>(volume->volume().lattice()));
  ASSERT_TRUE(drawn.cut(sim.incisions().front().points_m, sim.incisions().front().tips_m));
  ASSERT_TRUE(validate(drawn.mesh()).ok());
  // A frame 50 ms after the cut, and one a second after it.
  for (int s = 1; s <= 500; ++s, ++k) {
    (void)liver.step(k);
    if (s != 25 && s != 500) continue;
    follow();
    r->recut_solid(id, drawn.mesh());
    capture(s == 25 ? early : late);
  }
  ASSERT_EQ(late.frames, 1u);

  if (const char* dump = std::getenv("BISTURI_DUMP_WOUND")) {
    for (auto [name, cap] : {std::pair{"before", &before}, {"early", &early}, {"late", &late}})
      write_png(std::string(dump) + "/" + name + ".png", kSize, kSize, cap->pixels.data(),
                kSize * 4);  // the left eye
  }
  const HeadsetDescription& h = r->options().headset;
  for (int e = 0; e < 2; ++e) {
    std::vector<glm::dvec2> path;
    for (const glm::dvec3& p : sim.incisions().front().points_m)
      path.push_back(testing::project(h, facing_the_cut(), e, sim::sim_to_scene(p)));
    std::size_t changed = 0, changed_near = 0, interior_before = 0, interior_early = 0,
                interior_late = 0, interior_far = 0;
    for (std::uint32_t y = 0; y < kSize; ++y) {
      for (std::uint32_t x = 0; x < kSize; ++x) {
        const std::uint8_t* a = before.at(e, x, y);
        const std::uint8_t* b = late.at(e, x, y);
        const double d = testing::distance_to_polyline(path, {x + 0.5, y + 0.5});
        interior_before += interior_hue(a);
        interior_early += interior_hue(early.at(e, x, y));
        interior_late += interior_hue(b);
        interior_far += interior_hue(b) && d > 12.0;
        const bool differs =
            std::abs(a[0] - b[0]) + std::abs(a[1] - b[1]) + std::abs(a[2] - b[2]) > 24;
        if (!differs) continue;
        ++changed;
        changed_near += d <= 12.0;
      }
    }
    std::printf(
        "eye %d: changed %zu (near %zu), interior before %zu, 50 ms %zu, 1 s %zu (far %zu)\n", e,
        changed, changed_near, interior_before, interior_early, interior_late, interior_far);
    // No interior before the cut; a line of it 50 ms after, a slit several times its area a
    // second later (its walls); all of it within 12 pixels (7 mm) of the blade's path (the
    // walls close the wound, so the liver is not drawn two-sided and no back face shows), and
    // most of what changed (the rest: shading where the opening wound pulls the surface round
    // it; in the right eye 147 pixels against 560 near the path).
    EXPECT_EQ(interior_before, 0u) << "eye " << e;
    EXPECT_GT(interior_early, 10u) << "eye " << e;
    EXPECT_GT(interior_late, 150u) << "eye " << e;
    EXPECT_GT(interior_late, 3 * interior_early) << "eye " << e;
    EXPECT_LT(interior_far, interior_late / 50) << "eye " << e;
    EXPECT_GT(changed_near, 3 * (changed - changed_near)) << "eye " << e;
  }
}

}  // namespace
}  // namespace bisturi::render
