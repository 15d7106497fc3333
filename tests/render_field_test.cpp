// The operating field's light: the side of an organ away from the key light is still lit (no
// black void inside the silhouette), and with the field lamp on nearer tissue is brighter than
// farther tissue of the same material and normal, a depth cue the plain light does not give.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <optional>
#include <span>
#include <vector>

#include <glm/common.hpp>

#include "bisturi/runtime/render/drape_mesh.h"
#include "bisturi/runtime/render/instrument_mesh.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/shapes.h"
#include "render_test_support.h"

namespace bisturi::render {
namespace {

using testing::Capture;
using testing::RendererFixture;

constexpr std::uint32_t kSize = 192;

bool background(const std::uint8_t* px) {
  return px[0] == 0 && px[1] == 0 && px[2] == 0;
}

TEST(DrapeSheet, LiesUnderTheSolidsFacingUpAndReachesPastThem) {
  // Solids in [0, 100] x [0, 60] x [40, 90] mm: the sheet 2 mm under their lowest point, facing
  // up, reaching the larger side (100 mm) past them each way.
  const Dlfl sheet = drape_sheet({0.0, 0.0, 40.0}, {100.0, 60.0, 90.0});
  glm::dvec3 lo(1e9), hi(-1e9);
  for (std::uint32_t i = 0; i < sheet.vertex_capacity(); ++i) {
    if (!sheet.alive(VertexId(i))) continue;
    const glm::dvec3& p = sheet.position(VertexId(i));
    EXPECT_DOUBLE_EQ(p.z, 38.0);
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  EXPECT_NEAR(lo.x, -100.0, 1e-9);
  EXPECT_NEAR(hi.x, 200.0, 1e-9);
  EXPECT_NEAR(lo.y, -120.0, 1e-9);
  EXPECT_NEAR(hi.y, 180.0, 1e-9);
  std::size_t faces = 0;
  for (std::uint32_t f = 0; f < sheet.face_capacity(); ++f) {
    // The hole round the sheet's edge is a labelled face of its own, not drawn.
    if (!sheet.alive(FaceId(f)) || sheet.is_bounding(FaceId(f))) continue;
    ++faces;
    // The face's turn seen from above: counter-clockwise (its area along +z positive).
    double area_z = 0.0;
    const CornerId first = sheet.first_corner(FaceId(f));
    CornerId c = first;
    do {
      const glm::dvec3& a = sheet.position(sheet.vertex(c));
      const glm::dvec3& b = sheet.position(sheet.vertex(sheet.next(c)));
      area_z += a.x * b.y - b.x * a.y;
      c = sheet.next(c);
    } while (c != first);
    EXPECT_GT(area_z, 0.0) << "face " << f << " faces down";
  }
  EXPECT_EQ(faces, 24u * 24u);
}

class RenderFieldTest : public RendererFixture {};

TEST_F(RenderFieldTest, TheSideAwayFromTheKeyLightIsNotBlack) {
  RendererOptions options;
  auto* r = make(options, kSize);
  REQUIRE_RENDERER(r);
  r->add_solid(testing::sphere_mm({0.0, 0.0, -200.0}, 40.0));
  Capture frame;
  r->set_sink(&frame);
  r->render(testing::at_origin());
  r->flush();
  ASSERT_EQ(frame.frames, 1u);
  std::vector<int> red;
  for (std::uint32_t y = 0; y < kSize; ++y)
    for (std::uint32_t x = 0; x < kSize; ++x)
      if (!background(frame.at(0, x, y))) red.push_back(frame.at(0, x, y)[0]);
  ASSERT_GT(red.size(), 1000u);
  std::sort(red.begin(), red.end());
  // The darkest percent of the sphere (its limb away from the light, lower left): the field's
  // scattered light keeps it above 95 of 255 in red (the plain hemisphere light gave 75).
  std::printf("darkest percent: red %d (darkest %d)\n", red[red.size() / 100], red.front());
  EXPECT_GT(red[red.size() / 100], 95) << "darkest " << red.front();
}

TEST_F(RenderFieldTest, ASolidCastsItsShadowOnTheShadowPlaneAndTheDrapeDoesNot) {
  // Seen from the origin down -z: a sheet at z = -300 mm facing the viewer and a sphere of
  // 15 mm at (60, 0, -150). Its shadow, its footprint on the sheet straight along z, is seen
  // nearer the middle than the sphere itself (at 60 / 300 against 60 / 150 of the view), a
  // dark disc on the lit sheet; without the shadow plane the sheet is lit there.
  const auto dark_pixels = [&](bool shadows) -> int {
    RendererOptions options;
    auto* r = make(options, kSize);
    if (r == nullptr) return -1;
    Material sheet;
    sheet.casts_shadow = false;
    r->add_solid(drape_sheet({-40.0, -40.0, -298.0}, {40.0, 40.0, -290.0}), sheet);
    r->add_solid(testing::sphere_mm({60.0, 0.0, -150.0}, 15.0));
    if (shadows) r->set_shadow_plane(-300.0);
    Capture frame;
    r->set_sink(&frame);
    r->render(testing::at_origin());
    r->flush();
    int dark = 0;
    for (std::uint32_t y = 0; y < kSize; ++y)
      for (std::uint32_t x = 0; x < kSize; ++x) {
        const std::uint8_t* px = frame.at(0, x, y);
        if (!background(px) && px[0] < 60) ++dark;
      }
    return dark;
  };
  const int lit = dark_pixels(false);
  if (lit < 0) GTEST_SKIP() << "no Vulkan device";
  const int shadowed = dark_pixels(true);
  std::printf("dark pixels: %d without the shadow plane, %d with it\n", lit, shadowed);
  EXPECT_EQ(lit, 0);
  EXPECT_GT(shadowed, 30);
  EXPECT_LT(shadowed, 400) << "more than the sphere's footprint: the sheet shadows itself";
}

/// `mesh` without the faces whose centroid lies more than 0.8 of `radius` from `centre` along
/// `side`: a sphere with a round opening there.
Dlfl with_opening(const Dlfl& mesh, const glm::dvec3& centre, double radius,
                  const glm::dvec3& side) {
  const ExportedPolygons e = export_polygons(mesh);
  PolygonMesh kept;
  kept.positions = e.polygons.positions;
  for (std::size_t f = 0; f < e.polygons.face_count(); ++f) {
    const std::span<const std::uint32_t> face = e.polygons.face(f);
    glm::dvec3 centroid(0.0);
    for (const std::uint32_t v : face)
      centroid += e.polygons.positions[v];
    centroid /= static_cast<double>(face.size());
    if (glm::dot(centroid - centre, side) > 0.8 * radius) continue;
    kept.add_face(face);
  }
  return build_oriented_manifold(kept);
}

TEST_F(RenderFieldTest, AnEnclosedSolidShowsOnlyThroughAnOpeningOfItsEnclosure) {
  // A green lesion of 8 mm inside an organ of 30 mm, 150 mm in front of the eyes. Closed, the
  // organ hides it and it is not drawn; opened towards the eyes, it is drawn and seen through
  // the opening; opened away from them, the opening is a portal no eye sees it through.
  const glm::dvec3 centre{0.0, 0.0, -150.0};
  const Dlfl closed = testing::sphere_mm(centre, 30.0);
  struct Seen {
    FrameStats stats;
    int green = 0;
  };
  const auto look = [&](const Dlfl& organ, bool enclosed,
                        bool occlusion = true) -> std::optional<Seen> {
    RendererOptions options;
    if (occlusion) options.occlusion_cells = kOcclusionCells;
    auto* r = make(options, kSize);
    if (r == nullptr) return std::nullopt;
    const SolidId outer = r->add_solid(organ);
    Material lesion;
    lesion.colour = {0.05f, 0.8f, 0.05f};
    lesion.interior_colour = lesion.colour;
    const SolidId inner = r->add_solid(testing::sphere_mm(centre, 8.0), lesion);
    if (enclosed) r->set_enclosed_by(inner, outer);
    Capture frame;
    r->set_sink(&frame);
    Seen seen;
    seen.stats = r->render(testing::at_origin());
    r->flush();
    for (int eye = 0; eye < 2; ++eye)
      for (std::uint32_t y = 0; y < kSize; ++y)
        for (std::uint32_t x = 0; x < kSize; ++x) {
          const std::uint8_t* px = frame.at(eye, x, y);
          if (px[1] > px[0] + 40 && px[1] > px[2] + 40) ++seen.green;
        }
    return seen;
  };
  const auto shut = look(closed, true);
  if (!shut) GTEST_SKIP() << "no Vulkan device";
  // What the lesion would cost drawn: the closed organ's frame without any occlusion test.
  const std::size_t lesion_triangles =
      look(closed, false, false)->stats.triangles_drawn - shut->stats.triangles_drawn;
  EXPECT_GT(lesion_triangles, 0u);
  EXPECT_EQ(shut->green, 0);
  EXPECT_EQ(shut->stats.triangles_culled_occlusion, lesion_triangles);
  EXPECT_EQ(shut->stats.triangles_culled_portal, 0u);
  // Not declared enclosed, the lesion is still found hidden, behind the organ's near side.
  const auto undeclared = look(closed, false);
  EXPECT_EQ(undeclared->stats.triangles_culled_occlusion, lesion_triangles);
  EXPECT_EQ(undeclared->green, 0);

  const Dlfl front = with_opening(closed, centre, 30.0, {0.0, 0.0, 1.0});
  const auto through = look(front, true);
  const auto unculled = look(front, false, false);
  EXPECT_EQ(through->stats.triangles_culled_occlusion, 0u);
  EXPECT_EQ(through->stats.triangles_culled_portal, 0u);
  EXPECT_GT(through->green, 100);
  EXPECT_EQ(through->green, unculled->green);  // culling changed nothing that shows

  const auto behind = look(with_opening(closed, centre, 30.0, {0.0, 0.0, -1.0}), true);
  EXPECT_EQ(behind->green, 0);
  EXPECT_EQ(behind->stats.triangles_culled_portal, lesion_triangles);
  EXPECT_EQ(behind->stats.triangles_culled_occlusion, 0u);
  std::printf("green pixels: closed %d, opened towards the eyes %d, opened behind %d\n",
              shut->green, through->green, behind->green);
}

TEST_F(RenderFieldTest, OcclusionCullingLeavesEveryPixelAsItWas) {
  // An organ in chunks of 64 triangles, a sphere wholly behind it, one half behind it, the
  // drape under them all taking their shadows: with occlusion culling what is hidden is left
  // out, and both eyes' pixels are those drawn without it, from straight in front (where the
  // far sphere is hidden) and from a side.
  const auto draw = [&](bool occlusion, const HeadPose& pose, std::vector<std::uint8_t>& pixels,
                        int& hidden_level) -> std::optional<FrameStats> {
    RendererOptions options;
    options.levels.chunk_triangles = 64;
    if (occlusion) options.occlusion_cells = kOcclusionCells;
    auto* r = make(options, kSize);
    if (r == nullptr) return std::nullopt;
    Material drape;
    drape.casts_shadow = false;
    r->add_solid(drape_sheet({-60.0, -60.0, -242.0}, {60.0, 60.0, -118.0}), drape);
    r->add_solid(testing::sphere_mm({0.0, 0.0, -150.0}, 30.0));
    const SolidId hidden = r->add_solid(testing::sphere_mm({0.0, 0.0, -230.0}, 10.0));
    r->add_solid(testing::sphere_mm({34.0, 0.0, -200.0}, 12.0));
    r->set_shadow_plane(-244.0);
    Capture frame;
    r->set_sink(&frame);
    const FrameStats stats = r->render(pose);
    r->flush();
    pixels = frame.pixels;
    hidden_level = r->drawn_level(hidden);
    return stats;
  };
  const std::array<HeadPose, 2> poses{testing::at_origin(),
                                      look_at({40.0, 30.0, 0.0}, {0.0, 0.0, -150.0})};
  for (std::size_t k = 0; k < poses.size(); ++k) {
    std::vector<std::uint8_t> with, without;
    int hidden_with = 0, hidden_without = 0;
    const auto culled = draw(true, poses[k], with, hidden_with);
    if (!culled) GTEST_SKIP() << "no Vulkan device";
    const auto plain = draw(false, poses[k], without, hidden_without);
    std::printf(
        "pose %zu: %zu triangles drawn with occlusion culling (%zu left out), %zu without\n", k,
        culled->triangles_drawn, culled->triangles_culled_occlusion, plain->triangles_drawn);
    EXPECT_GT(culled->triangles_culled_occlusion, 0u) << "pose " << k;
    EXPECT_EQ(culled->triangles_drawn + culled->triangles_culled_occlusion, plain->triangles_drawn)
        << "pose " << k;
    EXPECT_EQ(plain->triangles_culled_occlusion, 0u);
    if (k == 0) {  // straight in front, the organ hides the far sphere from both eyes
      EXPECT_EQ(hidden_with, -1) << "the sphere behind the organ was drawn";
      EXPECT_GE(hidden_without, 0);
    }
    ASSERT_EQ(with.size(), without.size());
    std::size_t differ = 0;
    for (std::size_t i = 0; i < with.size(); ++i)
      differ += with[i] != without[i] ? 1 : 0;
    EXPECT_EQ(differ, 0u) << "pose " << k << ": bytes that occlusion culling changed";
  }
}

TEST_F(RenderFieldTest, AnOccludedPartOfASheetIsDarker) {
  // A sheet facing the viewer, its vertices left of x = 0 given an occlusion of 0.3: that half
  // is darker than the open half, which is as bright as without any occlusion.
  const auto mean_green = [&](bool occluded, bool left) -> double {
    RendererOptions options;
    auto* r = make(options, kSize);
    if (r == nullptr) return -1.0;
    const Dlfl sheet = drape_sheet({-40.0, -40.0, -298.0}, {40.0, 40.0, -290.0});
    const SolidId id = r->add_solid(sheet);
    if (occluded) {
      std::vector<float> open(sheet.vertex_capacity(), 1.0f);
      for (std::uint32_t v = 0; v < sheet.vertex_capacity(); ++v)
        if (sheet.alive(VertexId(v)) && sheet.position(VertexId(v)).x < 0.0) open[v] = 0.3f;
      r->set_occlusion(id, open);
    }
    Capture frame;
    r->set_sink(&frame);
    r->render(testing::at_origin());
    r->flush();
    double sum = 0.0;
    int n = 0;
    for (std::uint32_t y = kSize / 2 - 10; y < kSize / 2 + 10; ++y)
      for (std::uint32_t x = left ? kSize / 8 : kSize * 5 / 8;
           x < (left ? kSize * 3 / 8 : kSize * 7 / 8); ++x) {
        sum += frame.at(0, x, y)[1];
        ++n;
      }
    return sum / n;
  };
  const double plain_left = mean_green(false, true);
  if (plain_left < 0.0) GTEST_SKIP() << "no Vulkan device";
  const double dark_left = mean_green(true, true);
  const double open_right = mean_green(true, false);
  const double plain_right = mean_green(false, false);
  std::printf("green: left %.1f plain, %.1f occluded; right %.1f plain, %.1f beside it\n",
              plain_left, dark_left, plain_right, open_right);
  EXPECT_LT(dark_left, 0.8 * plain_left);
  EXPECT_NEAR(open_right, plain_right, 1.0);
}

/// A square of 80 mm tilted away from the viewer: its lower edge at 170 mm, its upper at 330.
Dlfl receding_square() {
  PolygonMesh grid = grid_mesh(8, 8, 10.0, true);
  for (auto& p : grid.positions) {
    const double y = p.y - 40.0;
    p = glm::dvec3(p.x - 40.0, y, -250.0 - 2.0 * y);
  }
  return build_oriented_manifold(grid);
}

/// Mean green (red may saturate) of the `n` topmost and bottommost lit pixels of the centre
/// column (far, near).
std::pair<double, double> far_and_near(const Capture& frame, std::size_t n) {
  std::vector<int> column;
  for (std::uint32_t y = 0; y < kSize; ++y) {
    const std::uint8_t* px = frame.at(0, kSize / 2, y);
    if (!background(px)) column.push_back(px[1]);
  }
  if (column.size() < 2 * n) return {0.0, 0.0};
  double far = 0.0, near = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    far += column[i];
    near += column[column.size() - 1 - i];
  }
  return {far / double(n), near / double(n)};
}

TEST_F(RenderFieldTest, TheFieldLampMakesNearerTissueBrighter) {
  std::pair<double, double> plain, lamp;
  for (const bool on : {false, true}) {
    RendererOptions options;
    options.field_lamp = on;
    auto* r = make(options, kSize);
    REQUIRE_RENDERER(r);
    r->add_solid(receding_square());
    // An instrument does not move the lamp's focus: the solids' centre, the square's.
    r->add_instrument(capsule_solid(1.0, 10.0), Material{}, glm::dmat4(1.0));
    Capture frame;
    r->set_sink(&frame);
    r->render(testing::at_origin());
    r->flush();
    ASSERT_EQ(frame.frames, 1u);
    (on ? lamp : plain) = far_and_near(frame, 6);
  }
  ASSERT_GT(plain.first, 0.0);
  ASSERT_GT(lamp.first, 0.0);
  // Same normal everywhere: without the lamp, near and far are within a few percent.
  EXPECT_NEAR(plain.second / plain.first, 1.0, 0.1);
  // With it, the near edge (170 mm) is brighter than the far one (330 mm) by a clear margin.
  EXPECT_GT(lamp.second / lamp.first, 1.3 * plain.second / plain.first)
      << "near " << lamp.second << ", far " << lamp.first;
}

}  // namespace
}  // namespace bisturi::render
