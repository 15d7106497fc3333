// The OpenXR sink end to end through the real Khronos loader and the simulated runtime
// (runtime/openxr_sim): a headset whose eyes have asymmetric fields of view that differ per eye,
// whose head moves, whose display is not 90 Hz, and which can fail to locate views, lose its
// session or go away. The renderer draws on the device the runtime made, straight into its
// swapchain; the runtime's log (BISTURI_XR_SIM_LOG, one JSON line per event) says what it
// located, what arrived in each layer and what was in the images. Validation is on for the shared
// device; every test that draws ends with zero messages.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"

namespace bisturi::render {
namespace {

constexpr std::uint32_t kSize = 128;
const glm::vec3 kClear{0.05f, 0.1f, 0.6f};  // blue: the sphere is reddish

using Json = nlohmann::json;

std::vector<Json> read_log(const std::filesystem::path& path) {
  std::vector<Json> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    lines.push_back(Json::parse(line));
  return lines;
}

std::vector<Json> events(const std::vector<Json>& log, const char* kind) {
  std::vector<Json> out;
  for (const auto& e : log) {
    if (e["event"] == kind) out.push_back(e);
  }
  return out;
}

/// Frames shown with a projection layer.
std::vector<Json> shown_frames(const std::vector<Json>& log) {
  std::vector<Json> out;
  for (const auto& f : events(log, "frame")) {
    if (f["layers"] == 1) out.push_back(f);
  }
  return out;
}

/// The runtime's answer to xrLocateViews, by the display time it was asked for.
std::map<std::int64_t, Json> located_by_time(const std::vector<Json>& log) {
  std::map<std::int64_t, Json> out;
  for (const auto& l : events(log, "located"))
    out[l["display_time_ns"].get<std::int64_t>()] = l;
  return out;
}

Dlfl sphere(double radius) {
  PhantomOptions p;
  p.shape = PhantomShape::Sphere;
  p.dims = {32, 32, 32};
  p.spacing = glm::dvec3(0.5);
  p.a = 6.0;
  Dlfl mesh = extract_isosurface(make_phantom(p));
  const glm::dvec3 phantom_centre(31 * 0.5 / 2.0);
  for (auto& x : mesh.positions())
    x = (x - phantom_centre) * (radius / 6.0);
  return mesh;
}

/// One frame of the runtime's loop, drawn when the runtime asks.
HeadsetFrame run_frame(OpenXrSink& sink, StereoRenderer* renderer) {
  HeadsetFrame f = sink.begin_frame();
  if (!f.began) return f;
  if (f.should_render && renderer != nullptr) renderer->render(f.head, f.eyes);
  sink.end_frame(f, f.should_render && renderer != nullptr);
  return f;
}

class OpenXrSimTest : public ::testing::Test {
 protected:
  void SetUp() override {
    // The simulated runtime, through the real loader (XR_RUNTIME_JSON is read at every
    // xrCreateInstance); its log goes to a fresh file per test.
    setenv("XR_RUNTIME_JSON", BISTURI_OPENXR_SIM_MANIFEST, 1);
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    log_ = std::filesystem::path(::testing::TempDir()) /
           (std::string("bisturi_xr_sim_") + info->name() + ".jsonl");
    std::filesystem::remove(log_);
    setenv("BISTURI_XR_SIM_LOG", log_.c_str(), 1);
    for (const char* name :
         {"BISTURI_XR_SIM_FORMATS", "BISTURI_XR_SIM_EXIT_AFTER", "BISTURI_XR_SIM_HZ",
          "BISTURI_XR_SIM_STILL", "BISTURI_XR_SIM_INVALID_VIEWS", "BISTURI_XR_SIM_LOSE_AFTER",
          "BISTURI_XR_SIM_LOST_MS", "BISTURI_XR_SIM_LOSE_INSTANCE_AFTER",
          "BISTURI_XR_SIM_TRIGGER_FRAMES"}) {
      unsetenv(name);
    }
  }

  /// A sink on the simulated headset (kSize per eye, validation on), the sphere's centre 0.45 m
  /// straight ahead of LOCAL's origin; null (and the test skipped) without a Vulkan device.
  std::unique_ptr<OpenXrSink> sink(OpenXrSinkOptions o = {}) {
    o.validation = true;
    o.eye_width = kSize;
    o.eye_height = kSize;
    o.field_position_m = {0.0, 0.0, -0.45};
    try {
      return std::make_unique<OpenXrSink>(o);
    } catch (const XrUnavailable& e) {
      skipped_ = e.what();
      return nullptr;
    }
  }

  std::unique_ptr<StereoRenderer> renderer(OpenXrSink& headset, double radius_mm = 70.0) {
    RendererOptions options;
    options.clear_colour = kClear;
    auto r = std::make_unique<StereoRenderer>(options, headset);
    r->add_solid(sphere(radius_mm));
    r->set_sink(&headset);
    return r;
  }

  static void expect_no_validation(const OpenXrSink& s) {
    std::string log;
    for (const std::string& m : s.validation_log())
      log += m + "\n";
    EXPECT_EQ(s.validation_messages(), 0u) << log;
  }

  std::filesystem::path log_;
  std::string skipped_;
};

TEST_F(OpenXrSimTest, EveryLayerCarriesExactlyTheViewsTheRuntimeLocated) {
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  constexpr int kFrames = 10;
  for (int i = 0; i < kFrames; ++i)
    run_frame(*s, r.get());
  r->flush();
  expect_no_validation(*s);
  EXPECT_EQ(s->stats().frames_submitted, static_cast<std::uint64_t>(kFrames - 1));
  r.reset();
  s.reset();

  const auto log = read_log(log_);
  const auto located = located_by_time(log);
  const auto shown = shown_frames(log);
  ASSERT_EQ(shown.size(), static_cast<std::size_t>(kFrames - 1));
  std::vector<double> xs;
  for (const auto& f : shown) {
    const auto it = located.find(f["display_time_ns"].get<std::int64_t>());
    ASSERT_NE(it, located.end()) << "a layer for a display time never located: " << f.dump();
    EXPECT_EQ(it->second["valid"], true);
    EXPECT_EQ(f["space"], it->second["space"]) << "the layer's space is the one located in";
    for (std::size_t e = 0; e < 2; ++e) {
      const Json& sent = f["views"][e];
      const Json& got = it->second["views"][e];
      // Bit for bit (both are the floats as %.9g): the layer is the located view.
      EXPECT_EQ(sent["position"], got["position"]) << "eye " << e;
      EXPECT_EQ(sent["orientation"], got["orientation"]) << "eye " << e;
      EXPECT_EQ(sent["fov"], got["fov"]) << "eye " << e;
      EXPECT_EQ(sent["rect"], Json({0, 0, kSize, kSize}));
    }
    xs.push_back(f["views"][0]["position"][0].get<double>());
  }
  // The headset's fields of view are asymmetric and differ per eye: no fixed frustum is them.
  const Json& fov0 = shown[0]["views"][0]["fov"];
  const Json& fov1 = shown[0]["views"][1]["fov"];
  EXPECT_NE(fov0, fov1);
  EXPECT_NE(-fov0[0].get<double>(), fov0[1].get<double>());
  // The head moved between frames, and each layer followed it.
  EXPECT_GT(*std::max_element(xs.begin(), xs.end()) - *std::min_element(xs.begin(), xs.end()),
            1e-4);
}

TEST_F(OpenXrSimTest, FramesAreDrawnIntoTheSwapchainOnTheSharedDeviceWithoutACpuCopy) {
  setenv("BISTURI_XR_SIM_STILL", "1", 1);  // the sphere stays in the middle of the view
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  // 160 mm at 0.45 m: it covers the centre of both images, whose asymmetric frusta look 10
  // degrees outwards and 7 down.
  auto r = renderer(*s, 160.0);
  EXPECT_TRUE(r->draws_into_headset());
  EXPECT_EQ(r->options().headset.eye_width, kSize);
  for (int i = 0; i < 4; ++i)
    run_frame(*s, r.get());
  r->flush();
  EXPECT_EQ(r->frames_read_back(), 0u) << "frames were copied to host memory";
  expect_no_validation(*s);
  r.reset();
  s.reset();

  const auto log = read_log(log_);
  const auto chains = events(log, "swapchain");
  ASSERT_EQ(chains.size(), 1u);
  EXPECT_EQ(chains[0]["array_size"], 2) << "one two-layer swapchain: one multiview pass";
  // Drawn into, never copied into: a copy would need the image as a transfer destination (and
  // the validation layer would have flagged one without it).
  EXPECT_EQ(chains[0]["usage"], Json({"color_attachment", "mutable_format"}));
  const auto shown = shown_frames(log);
  ASSERT_EQ(shown.size(), 3u);
  for (const auto& f : shown) {
    for (std::size_t e = 0; e < 2; ++e) {
      // What the runtime read from its own image: the sphere in the middle (reddish), the
      // clear colour around it (blue), in both layers.
      const Json& centre = f["views"][e]["centre_rgba"];
      EXPECT_GT(centre[0].get<int>(), centre[2].get<int>()) << "eye " << e << ": " << centre;
      const Json& mean = f["views"][e]["mean_rgb"];
      EXPECT_GT(mean[2].get<double>(), 60.0) << "eye " << e << " is not mostly clear colour";
    }
    EXPECT_NE(f["views"][0]["checksum"], f["views"][1]["checksum"]) << "both eyes alike";
  }
}

TEST_F(OpenXrSimTest, DisplayRateAndDroppedFramesAreTheRuntimes) {
  setenv("BISTURI_XR_SIM_HZ", "50", 1);  // 20 ms periods
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  for (int i = 0; i < 10; ++i) {
    run_frame(*s, r.get());
    if (i == 4) std::this_thread::sleep_for(std::chrono::milliseconds(70));  // miss some
  }
  const OpenXrSinkStats stats = s->stats();
  EXPECT_EQ(stats.display_period_ns, 20'000'000);
  EXPECT_EQ(stats.min_display_period_ns, 20'000'000);
  EXPECT_EQ(stats.max_display_period_ns, 20'000'000);
  r.reset();
  s.reset();
  // Refreshes missed, counted here from the runtime's own record of the frames' display times.
  const auto frames = events(read_log(log_), "frame");
  std::uint64_t missed = 0;
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const double gap =
        frames[i]["display_time_ns"].get<double>() - frames[i - 1]["display_time_ns"].get<double>();
    missed += static_cast<std::uint64_t>(std::llround(gap / 20e6)) - 1;
  }
  EXPECT_GE(missed, 2u) << "the 70 ms pause missed refreshes";
  EXPECT_EQ(stats.dropped_frames, missed);
}

TEST_F(OpenXrSimTest, InvalidViewLocationsAreNeverDrawnNorSubmitted) {
  // Frame 0 is only SYNCHRONIZED; frame 1, the first drawn, has no valid views yet; frames 3 and
  // 4 have none either (the runtime answers wild poses there).
  setenv("BISTURI_XR_SIM_INVALID_VIEWS", "1,3,4", 1);
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  std::vector<HeadsetFrame> frames;
  for (int i = 0; i < 7; ++i)
    frames.push_back(run_frame(*s, r.get()));
  const OpenXrSinkStats stats = s->stats();
  EXPECT_EQ(stats.invalid_view_locations, 3u);
  EXPECT_EQ(stats.frames_without_views, 1u);
  EXPECT_EQ(stats.frames_submitted, 5u);  // frames 2 to 6
  EXPECT_FALSE(frames[1].should_render);
  EXPECT_FALSE(frames[3].views_valid);
  EXPECT_TRUE(frames[3].should_render);
  // The reused views are the last valid ones, in the world as in the layer.
  EXPECT_EQ(frames[3].eyes[0].position_mm, frames[2].eyes[0].position_mm);
  EXPECT_EQ(frames[4].head.sample_time, frames[2].head.sample_time);
  expect_no_validation(*s);
  r.reset();
  s.reset();

  const auto log = read_log(log_);
  std::map<std::uint64_t, Json> located;
  for (const auto& l : events(log, "located"))
    located[l["frame"].get<std::uint64_t>()] = l;
  ASSERT_EQ(located.at(3)["valid"], false);
  const auto all = events(log, "frame");
  ASSERT_GE(all.size(), 7u);
  EXPECT_EQ(all[1]["layers"], 0) << "no views to show yet: no layer";
  for (const std::uint64_t reused : {3u, 4u}) {
    EXPECT_EQ(all[reused]["layers"], 1);
    EXPECT_EQ(all[reused]["views"][0]["position"], located.at(2)["views"][0]["position"]);
    EXPECT_EQ(all[reused]["views"][1]["orientation"], located.at(2)["views"][1]["orientation"]);
    EXPECT_NE(all[reused]["views"][0]["position"], located.at(reused)["views"][0]["position"]);
  }
  EXPECT_EQ(all[5]["views"][0]["position"], located.at(5)["views"][0]["position"]);
}

TEST_F(OpenXrSimTest, ALostSessionIsMadeAgainWhenTheHeadsetIsBack) {
  setenv("BISTURI_XR_SIM_LOSE_AFTER", "4", 1);
  setenv("BISTURI_XR_SIM_LOST_MS", "120", 1);
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  bool was_dark = false;
  const auto until = std::chrono::steady_clock::now() + std::chrono::seconds(5);
  while (s->stats().frames_submitted < 8 && std::chrono::steady_clock::now() < until) {
    run_frame(*s, r.get());
    if (s->stats().sessions_lost > 0 && !s->presenting()) was_dark = true;
  }
  const OpenXrSinkStats stats = s->stats();
  EXPECT_EQ(stats.sessions_lost, 1u);
  EXPECT_EQ(stats.sessions_recreated, 1u);
  EXPECT_GE(stats.frames_submitted, 8u);
  EXPECT_TRUE(was_dark) << "the sink said it presented while it had no session";
  EXPECT_TRUE(s->presenting());
  EXPECT_FALSE(s->stopped());
  std::vector<std::string> states;
  for (const XrStateChange& c : s->state_changes())
    states.push_back(c.state);
  const std::vector<std::string> want = {"IDLE",         "READY",        "SYNCHRONIZED", "VISIBLE",
                                         "FOCUSED",      "LOSS_PENDING", "IDLE",         "READY",
                                         "SYNCHRONIZED", "VISIBLE",      "FOCUSED"};
  EXPECT_EQ(states, want);
  for (std::size_t i = 1; i < s->state_changes().size(); ++i)
    EXPECT_GE(s->state_changes()[i].time, s->state_changes()[i - 1].time);
  expect_no_validation(*s);
  r.reset();
  s.reset();
  const auto log = read_log(log_);
  ASSERT_EQ(events(log, "session_created").size(), 2u);
  EXPECT_EQ(events(log, "session_destroyed").size(), 2u);
  EXPECT_EQ(events(log, "swapchain").size(), 2u);
  // The frames after the loss were drawn into the new swapchain (the sphere is in them).
  const auto shown = shown_frames(log);
  ASSERT_GE(shown.size(), 8u);
  EXPECT_GT(shown.back()["views"][0]["mean_rgb"][0].get<double>(), 0.0);
}

TEST_F(OpenXrSimTest, ARuntimeThatGoesAwayStopsPresentingCleanly) {
  setenv("BISTURI_XR_SIM_LOSE_INSTANCE_AFTER", "3", 1);
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  for (int i = 0; i < 8 && !s->stopped(); ++i)
    run_frame(*s, r.get());
  EXPECT_TRUE(s->stopped());
  EXPECT_FALSE(s->presenting());
  EXPECT_NE(s->stop_reason().find("going away"), std::string::npos) << s->stop_reason();
  EXPECT_EQ(s->stats().frames_submitted, 2u);
  const HeadsetFrame after = run_frame(*s, r.get());
  EXPECT_FALSE(after.began);
  r.reset();
  s.reset();  // tears down without throwing
}

TEST_F(OpenXrSimTest, TheRightControllersGripTriggerAndVibrationComeThroughTheRuntime) {
  setenv("BISTURI_XR_SIM_TRIGGER_FRAMES", "3-5", 1);
  OpenXrSinkOptions o;
  o.controller = true;
  auto s = sink(o);
  if (!s) GTEST_SKIP() << skipped_;
  auto r = renderer(*s);
  // Until the session is focused (after frame 0) no input reaches it, nor vibration.
  EXPECT_FALSE(s->vibrate(0.5f, 0.02));
  const HeadsetFrame first = run_frame(*s, r.get());
  EXPECT_FALSE(first.controller.active);
  std::vector<HeadsetFrame> frames{first};
  for (int i = 1; i < 8; ++i)
    frames.push_back(run_frame(*s, r.get()));
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const ControllerState& c = frames[i].controller;
    ASSERT_TRUE(c.active) << "frame " << i;
    EXPECT_EQ(c.trigger, i >= 3 && i <= 5 ? 1.0f : 0.0f) << "frame " << i;
    // The simulated grip is 0.30 m below LOCAL's origin: the world pose maps back there.
    EXPECT_NEAR(s->to_reference_m(c.grip_mm).y, -0.30, 1e-5) << "frame " << i;
  }
  EXPECT_NE(frames[1].controller.grip_mm, frames[7].controller.grip_mm) << "the hand moved";
  EXPECT_TRUE(s->vibrate(0.5f, 0.02));
  EXPECT_TRUE(s->vibrate(1.0f, 0.0));  // the shortest vibration the runtime has
  EXPECT_THROW(s->vibrate(1.5f, 0.02), RenderError);
  EXPECT_EQ(s->stats().vibrations, 2u);
  expect_no_validation(*s);
  r.reset();
  s.reset();
  const auto log = read_log(log_);
  const auto haptics = events(log, "haptic");
  ASSERT_EQ(haptics.size(), 2u);
  EXPECT_DOUBLE_EQ(haptics[0]["amplitude"].get<double>(), 0.5);
  EXPECT_EQ(haptics[0]["duration_ns"], 20'000'000);
  EXPECT_EQ(haptics[1]["duration_ns"], -1) << "XR_MIN_HAPTIC_DURATION";
  EXPECT_EQ(events(log, "attach").size(), 1u);
}

TEST_F(OpenXrSimTest, StageSpaceWhenAskedAndOffered) {
  OpenXrSinkOptions o;
  o.stage_space = true;
  auto s = sink(o);
  if (!s) GTEST_SKIP() << skipped_;
  EXPECT_EQ(s->reference_space(), "STAGE");
  auto r = renderer(*s);
  for (int i = 0; i < 3; ++i)
    run_frame(*s, r.get());
  r.reset();
  s.reset();
  const auto log = read_log(log_);
  const auto shown = shown_frames(log);
  ASSERT_EQ(shown.size(), 2u);
  EXPECT_EQ(shown[0]["space"], 3) << "XR_REFERENCE_SPACE_TYPE_STAGE";
  // STAGE's origin is on the floor: the eyes are about 1.6 m up.
  EXPECT_NEAR(shown[0]["views"][0]["position"][1].get<double>(), 1.6, 0.1);
}

TEST_F(OpenXrSimTest, BgraSwapchainsShowTheSameColours) {
  setenv("BISTURI_XR_SIM_STILL", "1", 1);
  std::array<Json, 2> centre;
  for (int run = 0; run < 2; ++run) {
    setenv("BISTURI_XR_SIM_FORMATS", run == 0 ? "rgba_srgb" : "bgra_srgb", 1);
    std::filesystem::remove(log_);
    auto s = sink();
    if (!s) GTEST_SKIP() << skipped_;
    EXPECT_EQ(s->swapchain_format(),
              run == 0 ? "VK_FORMAT_R8G8B8A8_SRGB" : "VK_FORMAT_B8G8R8A8_SRGB");
    auto r = renderer(*s);
    for (int i = 0; i < 2; ++i)
      run_frame(*s, r.get());
    expect_no_validation(*s);
    r.reset();
    s.reset();
    const auto shown = shown_frames(read_log(log_));
    ASSERT_EQ(shown.size(), 1u);
    centre[static_cast<std::size_t>(run)] = shown[0]["views"][0]["centre_rgba"];
  }
  // The runtime reads its BGRA image back as RGBA: the same colour as the RGBA swapchain's.
  EXPECT_EQ(centre[0], centre[1]);
}

TEST_F(OpenXrSimTest, RuntimeWithoutAnSrgbFormatIsRefusedClearly) {
  setenv("BISTURI_XR_SIM_FORMATS", "rgba_unorm,rgba16f", 1);
  try {
    OpenXrSink s;
    FAIL() << "a sink was made without a usable swapchain format";
  } catch (const XrUnavailable& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("bisturi simulated headset"), std::string::npos) << what;
    EXPECT_NE(what.find("no sRGB RGBA8 swapchain format"), std::string::npos) << what;
    EXPECT_NE(what.find("headless"), std::string::npos) << what;
  }
  // Everything made before the refusal was taken down again.
  const auto log = read_log(log_);
  EXPECT_EQ(events(log, "session_destroyed").size(), 1u);
  EXPECT_EQ(events(log, "instance_destroyed").size(), 1u);
}

TEST_F(OpenXrSimTest, EyeSizesTheRuntimeCannotTakeAreRefusedNamingBoth) {
  OpenXrSinkOptions o;
  o.eye_width = 5000;
  o.eye_height = 2;
  try {
    OpenXrSink s(o);
    FAIL() << "a swapchain wider than the runtime allows was made";
  } catch (const XrUnavailable& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("5000x2"), std::string::npos) << what;
    EXPECT_NE(what.find("4096x4096"), std::string::npos) << what;
  }
}

TEST_F(OpenXrSimTest, TheUserEndingTheSessionStopsPresentingWithoutFailing) {
  setenv("BISTURI_XR_SIM_EXIT_AFTER", "3", 1);  // the user quits after three frames
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  for (int i = 0; i < 8 && !s->stopped(); ++i)
    run_frame(*s, nullptr);
  EXPECT_TRUE(s->stopped());
  EXPECT_FALSE(s->presenting());
  EXPECT_EQ(s->session_state(), "EXITING");
  EXPECT_NE(s->stop_reason().find("EXITING"), std::string::npos) << s->stop_reason();
  EXPECT_EQ(s->stats().frames_begun, 3u);
  s.reset();
  const auto log = read_log(log_);
  EXPECT_EQ(events(log, "frame").size(), 3u);
  EXPECT_EQ(events(log, "end_session").size(), 1u);
  ASSERT_EQ(events(log, "request_exit").size(), 1u);
  EXPECT_EQ(events(log, "request_exit")[0]["by"], "user");
}

TEST_F(OpenXrSimTest, WaitFramePacesTheLoopToTheDisplay) {
  setenv("BISTURI_XR_SIM_HZ", "50", 1);
  auto s = sink();
  if (!s) GTEST_SKIP() << skipped_;
  run_frame(*s, nullptr);
  const auto start = std::chrono::steady_clock::now();
  constexpr int kFrames = 10;
  for (int i = 0; i < kFrames; ++i)
    run_frame(*s, nullptr);
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // Ten frames at 50 Hz take ten periods of 20 ms (less the part of the first already gone).
  EXPECT_GT(ms, 170.0);
  EXPECT_GT(s->stats().wait_frame_ms, 150.0);
}

TEST(OpenXrSinkNoRuntimeTest, SaysSoClearlyAndNamesTheMissingManifest) {
  setenv("XR_RUNTIME_JSON", "/nonexistent/bisturi_no_runtime.json", 1);
  try {
    OpenXrSink sink;
    FAIL() << "an OpenXR sink was created without a runtime";
  } catch (const XrUnavailable& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("OpenXR"), std::string::npos) << what;
    EXPECT_NE(what.find("headless"), std::string::npos) << what;
    EXPECT_NE(what.find("/nonexistent/bisturi_no_runtime.json, which does not exist"),
              std::string::npos)
        << what;
  }
}

}  // namespace
}  // namespace bisturi::render
