// The stereo renderer on whatever Vulkan device there is (Mesa's lavapipe on machines without a
// GPU), with the Khronos validation layer on and its messages counted: every test ends with zero.
// Image checks compare the rendered eyes with pixels computed by ray casting the same sphere.

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/instrument_mesh.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"

namespace bisturi::render {
namespace {

constexpr std::uint32_t kSize = 256;

/// Keeps a copy of the last frame.
struct CaptureSink : FrameSink {
  std::vector<std::uint8_t> pixels;
  std::uint64_t frames = 0;
  StereoFrame last;
  void consume(const StereoFrame& frame) override {
    pixels.assign(frame.pixels.begin(), frame.pixels.end());
    last = frame;
    last.pixels = {};
    ++frames;
  }
  [[nodiscard]] bool lit(int eye, std::uint32_t x, std::uint32_t y) const {
    const std::size_t i = (static_cast<std::size_t>(eye) * kSize * kSize + y * kSize + x) * 4;
    return pixels[i] + pixels[i + 1] + pixels[i + 2] > 0;
  }
};

/// A marching-cubes sphere (phantom), scaled and moved to `centre` with `radius` (mm).
Dlfl sphere_solid(const glm::dvec3& centre, double radius) {
  PhantomOptions p;
  p.shape = PhantomShape::Sphere;
  p.dims = {40, 40, 40};
  p.spacing = glm::dvec3(0.5);
  p.a = 8.0;
  Dlfl mesh = extract_isosurface(make_phantom(p));
  const glm::dvec3 phantom_centre(39 * 0.5 / 2.0);
  for (auto& x : mesh.positions())
    x = centre + (x - phantom_centre) * (radius / 8.0);
  return mesh;
}

HeadsetDescription test_headset() {
  HeadsetDescription h;
  h.eye_width = kSize;
  h.eye_height = kSize;
  h.ipd_mm = 64.0;
  return h;  // +-45 degrees per eye, symmetric
}

/// Pixels whose centre ray from the eye hits the sphere (head at the origin looking down -z).
std::vector<char> expected_mask(const HeadsetDescription& h, int eye, const glm::dvec3& centre,
                                double radius) {
  const EyeFov& fov = h.fov[static_cast<std::size_t>(eye)];
  const double tl = std::tan(double{fov.angle_left}), tr = std::tan(double{fov.angle_right});
  const double tu = std::tan(double{fov.angle_up}), td = std::tan(double{fov.angle_down});
  const glm::dvec3 origin((eye == 0 ? -0.5 : 0.5) * h.ipd_mm, 0.0, 0.0);
  std::vector<char> mask(std::size_t{kSize} * kSize, 0);
  for (std::uint32_t y = 0; y < kSize; ++y) {
    for (std::uint32_t x = 0; x < kSize; ++x) {
      const glm::dvec3 d = glm::normalize(
          glm::dvec3(tl + (x + 0.5) / kSize * (tr - tl), tu - (y + 0.5) / kSize * (tu - td), -1.0));
      const glm::dvec3 oc = centre - origin;
      const double along = glm::dot(oc, d);
      const double miss2 = glm::dot(oc, oc) - along * along;
      mask[y * kSize + x] = along > 0 && miss2 < radius * radius ? 1 : 0;
    }
  }
  return mask;
}

struct MaskStats {
  std::size_t lit = 0, expected = 0, mismatched = 0;
  double centroid_x = 0.0, expected_centroid_x = 0.0;
};

MaskStats compare(const CaptureSink& sink, int eye, const std::vector<char>& expected) {
  MaskStats s;
  double sx = 0.0, ex = 0.0;
  for (std::uint32_t y = 0; y < kSize; ++y) {
    for (std::uint32_t x = 0; x < kSize; ++x) {
      const bool got = sink.lit(eye, x, y);
      const bool want = expected[y * kSize + x] != 0;
      s.lit += got;
      s.expected += want;
      s.mismatched += got != want;
      if (got) sx += x + 0.5;
      if (want) ex += x + 0.5;
    }
  }
  s.centroid_x = s.lit > 0 ? sx / static_cast<double>(s.lit) : -1.0;
  s.expected_centroid_x = s.expected > 0 ? ex / static_cast<double>(s.expected) : -1.0;
  return s;
}

class RenderTest : public ::testing::Test {
 protected:
  /// A renderer with validation on, owned by the fixture (checked in TearDown); null and the
  /// reason in skipped_ when there is no Vulkan device.
  StereoRenderer* make(RendererOptions options = {}) {
    options.headset = test_headset();
    options.validation = true;
    try {
      renderers_.push_back(std::make_unique<StereoRenderer>(options));
      return renderers_.back().get();
    } catch (const NoVulkanDevice& e) {
      skipped_ = e.what();
      return nullptr;
    }
  }

  void TearDown() override {
    for (const auto& r : renderers_) {
      std::string log;
      for (const std::string& m : r->validation_log())
        log += m + "\n";
      EXPECT_EQ(r->validation_messages(), 0u) << log;
    }
  }

  HeadPose origin_pose() const {
    HeadPose pose;  // at the origin, looking down -z, y up
    pose.sample_time = PoseClock::now();
    return pose;
  }

  std::vector<std::unique_ptr<StereoRenderer>> renderers_;
  std::string skipped_;
};

#define REQUIRE_RENDERER(r) \
  if (!(r)) GTEST_SKIP() << "no Vulkan device, rendering not tested: " << skipped_

TEST_F(RenderTest, SphereCoversExpectedPixelsInEachEyeWithExpectedDisparity) {
  auto r = make();
  REQUIRE_RENDERER(r);
  const glm::dvec3 centre(0.0, 10.0, -200.0);
  const double radius = 40.0;
  const Dlfl sphere = sphere_solid(centre, radius);
  r->add_solid(sphere);
  CaptureSink sink;
  r->set_sink(&sink);
  const FrameStats stats = r->render(origin_pose());
  r->flush();
  ASSERT_EQ(sink.frames, 1u);
  EXPECT_GE(stats.draw_calls, 1u);

  std::array<MaskStats, 2> eye{};
  for (int e = 0; e < 2; ++e) {
    eye[static_cast<std::size_t>(e)] =
        compare(sink, e, expected_mask(r->options().headset, e, centre, radius));
    const MaskStats& s = eye[static_cast<std::size_t>(e)];
    ASSERT_GT(s.expected, 1000u);
    // Only the outline may differ (the tessellated sphere lies just inside the true one).
    EXPECT_LT(static_cast<double>(s.mismatched), 0.04 * static_cast<double>(s.expected))
        << "eye " << e << ": " << s.lit << " lit, " << s.expected << " expected";
    EXPECT_NEAR(s.centroid_x, s.expected_centroid_x, 0.5) << "eye " << e;
  }
  // The left eye sits to the left, so the sphere appears further right in it.
  const double disparity = eye[0].centroid_x - eye[1].centroid_x;
  const double expected = eye[0].expected_centroid_x - eye[1].expected_centroid_x;
  EXPECT_GT(expected, 30.0);  // about ipd / distance * pixels per tangent: 64 / 200 * 128
  EXPECT_NEAR(disparity, expected, 0.5);
  // Nothing above or below the eyes' shared rows: same vertical position in both eyes.
  EXPECT_LT(static_cast<double>(eye[0].lit > eye[1].lit ? eye[0].lit - eye[1].lit
                                                        : eye[1].lit - eye[0].lit),
            0.02 * static_cast<double>(eye[0].lit));
}

TEST_F(RenderTest, LocatedEyesAreDrawnWithTheirOwnPosesAndFieldsOfView) {
  auto r = make();
  REQUIRE_RENDERER(r);
  const glm::dvec3 centre(0.0, 10.0, -200.0);
  const double radius = 40.0;
  r->add_solid(sphere_solid(centre, radius));
  CaptureSink sink;
  r->set_sink(&sink);
  // As a runtime locates them: each eye its own asymmetric frustum (the renderer's headset
  // description says +-45 degrees), at +-32 mm, looking down -z.
  HeadsetDescription located = r->options().headset;
  located.fov[0] = {-0.70f, 0.55f, 0.60f, -0.75f};
  located.fov[1] = {-0.55f, 0.70f, 0.60f, -0.75f};
  std::array<EyePose, 2> eyes;
  for (std::size_t e = 0; e < 2; ++e) {
    eyes[e].position_mm = {(e == 0 ? -0.5 : 0.5) * located.ipd_mm, 0.0, 0.0};
    eyes[e].fov = located.fov[e];
  }
  r->render(origin_pose(), eyes);
  r->flush();
  ASSERT_EQ(sink.frames, 1u);
  for (int e = 0; e < 2; ++e) {
    const MaskStats s = compare(sink, e, expected_mask(located, e, centre, radius));
    ASSERT_GT(s.expected, 1000u);
    EXPECT_LT(static_cast<double>(s.mismatched), 0.04 * static_cast<double>(s.expected))
        << "eye " << e << ": " << s.lit << " lit, " << s.expected << " expected";
    EXPECT_NEAR(s.centroid_x, s.expected_centroid_x, 0.5) << "eye " << e;
    // The headset description's symmetric frustum would put it elsewhere.
    const MaskStats wrong = compare(sink, e, expected_mask(r->options().headset, e, centre, radius));
    EXPECT_GT(std::abs(wrong.expected_centroid_x - s.centroid_x), 5.0) << "eye " << e;
  }
}

TEST_F(RenderTest, OpenSheetsShowTheirInteriorFromBehindAndClosedSolidsCullBackFaces) {
  auto r = make();
  REQUIRE_RENDERER(r);
  // A single-sided square facing +z, centred on the view axis 200 mm ahead.
  PolygonMesh grid = grid_mesh(8, 8, 10.0, true);
  for (auto& p : grid.positions)
    p += glm::dvec3(-40.0, -40.0, -200.0);
  const auto f = grid.face(0);
  const glm::dvec3 normal = glm::cross(grid.positions[f[1]] - grid.positions[f[0]],
                                       grid.positions[f[2]] - grid.positions[f[0]]);
  ASSERT_GT(std::abs(normal.z), 0.0);
  r->add_solid(build_oriented_manifold(grid));
  CaptureSink sink;
  r->set_sink(&sink);

  const auto lit_pixels = [&] {
    std::size_t n = 0;
    for (int e = 0; e < 2; ++e)
      for (std::uint32_t y = 0; y < kSize; ++y)
        for (std::uint32_t x = 0; x < kSize; ++x)
          n += sink.lit(e, x, y);
    return n;
  };
  // From the side the faces point to, and from behind (at z = -400 looking back at it).
  const HeadPose front = normal.z > 0 ? origin_pose() : look_at({0, 0, -400}, {0, 0, -200});
  const HeadPose back = normal.z > 0 ? look_at({0, 0, -400}, {0, 0, -200}) : origin_pose();
  const FrameStats front_stats = r->render(front);
  r->flush();
  const std::size_t front_lit = lit_pixels();
  const FrameStats back_stats = r->render(back);
  r->flush();
  const std::size_t back_lit = lit_pixels();
  EXPECT_GT(front_lit, 4000u);  // an 80 mm square at 200 mm: about 51 x 51 pixels per eye
  EXPECT_GE(front_stats.draw_calls, 1u);
  EXPECT_GE(back_stats.draw_calls, 1u);  // submitted, and dropped by the rasterizer
  // The sheet is open (a boundary loop): from behind, its inner side in the interior colour.
  EXPECT_EQ(back_lit, front_lit);
  const std::size_t centre = (std::size_t{kSize / 2} * kSize + kSize / 2) * 4;
  EXPECT_LT(sink.pixels[centre + 1], sink.pixels[centre] / 2) << "not the interior colour";

  // From inside a closed cube every face is a back face: culled, nothing drawn.
  auto closed = make();
  closed->add_solid(build_oriented_manifold(cube_mesh({-50.0, -50.0, -50.0}, 100.0)));
  closed->set_sink(&sink);
  closed->render(origin_pose());
  closed->flush();
  EXPECT_EQ(lit_pixels(), 0u);
}

TEST_F(RenderTest, SolidOutsideTheFrustumCostsNoDrawCall) {
  RendererOptions options;
  options.levels.derived_levels = false;
  auto r = make(options);
  REQUIRE_RENDERER(r);
  const Dlfl in_view = sphere_solid({0.0, 0.0, -200.0}, 20.0);
  const Dlfl behind = sphere_solid({0.0, 0.0, 300.0}, 20.0);
  const Dlfl beside = sphere_solid({-900.0, 0.0, -200.0}, 20.0);
  r->add_solid(in_view);
  const FrameStats alone = r->render(origin_pose());
  const SolidId b1 = r->add_solid(behind);
  const SolidId b2 = r->add_solid(beside);
  const FrameStats with_hidden = r->render(origin_pose());
  r->flush();
  EXPECT_GE(alone.draw_calls, 1u);
  EXPECT_EQ(with_hidden.draw_calls, alone.draw_calls);
  EXPECT_EQ(with_hidden.triangles_drawn, alone.triangles_drawn);
  EXPECT_EQ(with_hidden.solids_culled, 2u);
  EXPECT_EQ(r->drawn_level(b1), -1);
  EXPECT_EQ(r->drawn_level(b2), -1);
}

TEST_F(RenderTest, ChunksOutsideTheFrustumAreNotDrawn) {
  RendererOptions options;
  options.levels.derived_levels = false;
  options.levels.chunk_triangles = 512;
  auto r = make(options);
  REQUIRE_RENDERER(r);
  // A floor much wider than the view, 100 mm below the eyes, facing up.
  PolygonMesh floor = grid_mesh(120, 120, 20.0, true);
  for (auto& p : floor.positions)
    p = glm::dvec3(p.x - 1200.0, -100.0, -p.y + 1200.0);
  const Dlfl solid = build_oriented_manifold(floor);
  r->add_solid(solid);
  CaptureSink sink;
  r->set_sink(&sink);
  const FrameStats culled = r->render(look_at({0, 0, 0}, {0, -100, -300}));
  r->flush();
  std::size_t lit = 0;
  for (std::uint32_t y = 0; y < kSize; ++y)
    for (std::uint32_t x = 0; x < kSize; ++x)
      lit += sink.lit(0, x, y);
  const auto& level = r->levels(SolidId{0}).level(0);
  EXPECT_GT(lit, 1000u);
  EXPECT_GT(culled.chunks_culled, level.tree.chunks.size() / 2);
  EXPECT_EQ(culled.chunks_drawn + culled.chunks_culled, level.tree.chunks.size());
  EXPECT_LT(culled.triangles_drawn, level.triangle_count() / 2);
}

TEST_F(RenderTest, DeformedMeshRendersItsNewShape) {
  RendererOptions options;
  options.level_of_detail = false;  // one level throughout: its index buffer must stay
  auto r = make(options);
  REQUIRE_RENDERER(r);
  const glm::dvec3 centre(0.0, 0.0, -200.0);
  Dlfl sphere = sphere_solid(centre, 30.0);
  const SolidId id = r->add_solid(sphere);
  CaptureSink sink;
  r->set_sink(&sink);
  r->render(origin_pose());
  r->flush();
  const HeadsetDescription& h = r->options().headset;
  const MaskStats before = compare(sink, 0, expected_mask(h, 0, centre, 30.0));
  EXPECT_LT(static_cast<double>(before.mismatched), 0.04 * static_cast<double>(before.expected));

  // Deform: the sphere moves 40 mm to the right and grows to 45 mm radius (no topology change).
  const glm::dvec3 moved(40.0, 0.0, -200.0);
  for (auto& x : sphere.positions())
    x = moved + (x - centre) * 1.5;
  r->update_solid(id, sphere);
  const FrameStats stats = r->render(origin_pose());
  r->flush();
  EXPECT_EQ(stats.index_buffers_rebuilt, 0u);  // positions only: indices stay
  for (int e = 0; e < 2; ++e) {
    const MaskStats after = compare(sink, e, expected_mask(h, e, moved, 45.0));
    EXPECT_LT(static_cast<double>(after.mismatched), 0.04 * static_cast<double>(after.expected))
        << "eye " << e;
    EXPECT_NEAR(after.centroid_x, after.expected_centroid_x, 0.5);
  }
}

TEST_F(RenderTest, TopologyChangeRebuildsTheIndices) {
  auto r = make();
  REQUIRE_RENDERER(r);
  Dlfl mesh = build_oriented_manifold(cube_mesh({-20.0, -20.0, -220.0}, 40.0));
  const SolidId id = r->add_solid(mesh);
  const FrameStats first = r->render(origin_pose());
  EXPECT_GE(first.index_buffers_rebuilt, 1u);
  EXPECT_EQ(r->render(origin_pose()).index_buffers_rebuilt, 0u);
  // Split the front face along a diagonal: a new edge, a new topology version.
  const std::uint64_t version = mesh.topology_version();
  FaceId front;
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const CornerId c = mesh.first_corner(FaceId{f});
    if (mesh.alive(FaceId{f}) && mesh.position(mesh.vertex(c)).z > -181.0 &&
        mesh.position(mesh.vertex(mesh.next(c))).z > -181.0 &&
        mesh.position(mesh.vertex(mesh.next(mesh.next(c)))).z > -181.0) {
      front = FaceId{f};
    }
  }
  ASSERT_TRUE(front.valid());
  const CornerId c = mesh.first_corner(front);
  mesh.insert_edge(c, mesh.next(mesh.next(c)));
  ASSERT_NE(mesh.topology_version(), version);
  r->update_solid(id, mesh);
  const FrameStats after = r->render(origin_pose());
  r->flush();
  EXPECT_EQ(after.index_buffers_rebuilt, 1u);
  EXPECT_EQ(r->levels(id).level(r->levels(id).source_level()).triangle_count(), 12u);
}

TEST_F(RenderTest, DistantSolidsUseCoarserLevels) {
  auto r = make();
  REQUIRE_RENDERER(r);
  const SolidId near_id = r->add_solid(sphere_solid({0.0, 0.0, -60.0}, 20.0));
  const SolidId far_id = r->add_solid(sphere_solid({0.0, 0.0, -3000.0}, 20.0));
  r->render(origin_pose());
  r->flush();
  const SolidLevels& levels = r->levels(far_id);
  ASSERT_GT(levels.level_count(), levels.source_level() + 1);
  std::string errors;
  for (std::size_t i = 0; i < levels.level_count(); ++i) {
    errors += std::to_string(levels.level(i).error_mm) + " mm (" +
              std::to_string(levels.level(i).triangle_count()) + " triangles); ";
  }
  EXPECT_GT(r->drawn_level(far_id), r->drawn_level(near_id)) << errors;
  EXPECT_EQ(static_cast<std::size_t>(r->drawn_level(far_id)), levels.level_count() - 1) << errors;
}

TEST_F(RenderTest, InstrumentsAreDrawnAtTheirPose) {
  auto r = make();
  REQUIRE_RENDERER(r);
  const Dlfl capsule = capsule_solid(4.0, 60.0);
  // The capsule's axis (+z) turned to +x, the shaft from x = 40 to x = 100 at z = -200.
  glm::dmat4 pose(0.0);
  pose[0] = glm::dvec4(0.0, 0.0, -1.0, 0.0);
  pose[1] = glm::dvec4(0.0, 1.0, 0.0, 0.0);
  pose[2] = glm::dvec4(1.0, 0.0, 0.0, 0.0);
  pose[3] = glm::dvec4(40.0, 0.0, -200.0, 1.0);
  const SolidId id = r->add_instrument(capsule, Material{{0.7f, 0.7f, 0.75f}}, pose);
  CaptureSink sink;
  r->set_sink(&sink);
  r->render(origin_pose());
  r->flush();
  EXPECT_NE(r->drawn_level(id), -1);
  // Right eye at x = 32: the capsule spans tangents 0.02 .. 0.52, the right half of the image.
  std::size_t right_half = 0, left_half = 0;
  for (std::uint32_t y = 0; y < kSize; ++y)
    for (std::uint32_t x = 0; x < kSize; ++x)
      (x < kSize / 2 ? left_half : right_half) += sink.lit(1, x, y);
  EXPECT_GT(right_half, 150u);  // about 43 x 5 pixels
  EXPECT_EQ(left_half, 0u);
}

TEST_F(RenderTest, PngSinkWritesFramesWithPosesAndLatency) {
  auto r = make();
  REQUIRE_RENDERER(r);
  r->add_solid(sphere_solid({0.0, 0.0, -200.0}, 20.0));
  const auto dir = std::filesystem::path(::testing::TempDir()) / "bisturi_render_png";
  std::filesystem::remove_all(dir);
  PngSink sink(dir, {PngLayout::PerEye, 1});
  r->set_sink(&sink);
  for (int i = 0; i < 3; ++i)
    r->render(origin_pose());
  r->flush();
  sink.finish();
  EXPECT_EQ(sink.images_written(), 6u);
  EXPECT_TRUE(std::filesystem::exists(dir / "frame_00002_left.png"));
  EXPECT_TRUE(std::filesystem::exists(dir / "frame_00002_right.png"));
  ASSERT_EQ(sink.latencies_ms().size(), 3u);
  for (const double ms : sink.latencies_ms())
    EXPECT_GE(ms, 0.0);
  std::ifstream csv(dir / "frames.csv");
  std::string line;
  int lines = 0;
  while (std::getline(csv, line))
    ++lines;
  EXPECT_EQ(lines, 4);
}

TEST(OpenXrSinkTest, WithoutARuntimeItSaysSoClearly) {
  if (std::getenv("XR_RUNTIME_JSON") != nullptr) GTEST_SKIP() << "an OpenXR runtime is named";
  try {
    OpenXrSink sink;
    FAIL() << "an OpenXR sink was created without a runtime";
  } catch (const XrUnavailable& e) {
    EXPECT_NE(std::string(e.what()).find("OpenXR"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("headless"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bisturi::render
