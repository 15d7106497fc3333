// The OpenXR sink end to end through the real Khronos loader and the simulated runtime
// (runtime/openxr_sim): frames rendered on lavapipe are uploaded into the runtime's swapchains, and
// the runtime's log (BISTURI_XR_SIM_LOG, one JSON line per event) says what arrived. Validation is
// on for the renderer and for the sink's own device; every test ends with zero messages.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

#include <glm/gtc/quaternion.hpp>
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

std::uint64_t fnv1a(std::span<const std::uint8_t> bytes) {
  std::uint64_t hash = 1469598103934665603ull;
  for (const std::uint8_t b : bytes)
    hash = (hash ^ b) * 1099511628211ull;
  return hash;
}

std::string hex(std::uint64_t value) {
  char text[17];
  std::snprintf(text, sizeof text, "%016llx", static_cast<unsigned long long>(value));
  return text;
}

std::vector<nlohmann::json> read_log(const std::filesystem::path& path) {
  std::vector<nlohmann::json> lines;
  std::ifstream in(path);
  for (std::string line; std::getline(in, line);)
    lines.push_back(nlohmann::json::parse(line));
  return lines;
}

std::vector<nlohmann::json> events(const std::vector<nlohmann::json>& log, const char* kind) {
  std::vector<nlohmann::json> out;
  for (const auto& e : log) {
    if (e["event"] == kind) out.push_back(e);
  }
  return out;
}

/// The expected view pose in OpenXR LOCAL, computed here from the documented convention (LPS mm
/// to metres, superior -> +y, anterior -> +z), independently of the sink's code.
struct ExpectedView {
  glm::dvec3 position;
  glm::dquat orientation;
};
ExpectedView expected_view(const HeadsetDescription& h, const HeadPose& head, int eye) {
  const glm::dvec3 eye_mm =
      head.position_mm +
      glm::mat3_cast(head.orientation) * glm::dvec3((eye == 0 ? -0.5 : 0.5) * h.ipd_mm, 0, 0);
  const glm::dquat turn = glm::angleAxis(-glm::half_pi<double>(), glm::dvec3(1, 0, 0));
  return {turn * eye_mm / 1000.0, turn * head.orientation};
}

/// Keeps what the sink was given for every frame it submitted, then passes the frame on.
struct Tee : FrameSink {
  explicit Tee(OpenXrSink& s) : sink(s) {}
  OpenXrSink& sink;
  struct Sent {
    HeadPose pose;
    std::array<std::string, 2> checksum;
    std::array<std::uint8_t, 4> centre{};
    std::array<std::uint8_t, 4> corner{};
  };
  std::vector<Sent> submitted;
  void consume(const StereoFrame& frame) override {
    const std::uint64_t before = sink.stats().frames_submitted;
    sink.consume(frame);
    if (sink.stats().frames_submitted == before) return;
    Sent s;
    s.pose = frame.pose;
    for (int e = 0; e < 2; ++e)
      s.checksum[static_cast<std::size_t>(e)] = hex(fnv1a(frame.eye(e)));
    const auto left = frame.eye(0);
    const std::size_t centre =
        (std::size_t{frame.eye_height / 2} * frame.eye_width + frame.eye_width / 2) * 4;
    for (std::size_t c = 0; c < 4; ++c) {
      s.centre[c] = left[centre + c];
      s.corner[c] = left[c];
    }
    submitted.push_back(s);
  }
};

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

/// A pose anterior of the origin (-y in LPS), looking at it with superior (+z) up, moved `dx` mm
/// to the patient's left: in OpenXR's LOCAL space the head stands at +z looking down -z.
HeadPose anterior_pose(double dx) {
  return look_at({dx, -300.0, 0.0}, {0.0, 0.0, 0.0}, {0.0, 0.0, 1.0});
}

StereoFrame synthetic_frame(std::vector<std::uint8_t>& pixels, std::uint32_t w, std::uint32_t h,
                            std::uint64_t index) {
  pixels.assign(std::size_t{w} * h * 4 * 2, 0);
  for (std::size_t i = 0; i < pixels.size(); ++i)
    pixels[i] = static_cast<std::uint8_t>((i * 7 + index) & 0xff);
  StereoFrame f;
  f.index = index;
  f.eye_width = w;
  f.eye_height = h;
  f.pixels = pixels;
  f.pose = anterior_pose(0.0);
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
    unsetenv("BISTURI_XR_SIM_FORMATS");
    unsetenv("BISTURI_XR_SIM_EXIT_AFTER");
    setenv("BISTURI_XR_SIM_HZ", "90", 1);
  }

  std::unique_ptr<StereoRenderer> renderer() {
    RendererOptions options;
    options.headset.eye_width = kSize;
    options.headset.eye_height = kSize;
    options.headset.ipd_mm = 64.0;
    options.headset.fov[0] = {-0.7f, 0.6f, 0.65f, -0.75f};  // asymmetric, as headsets have
    options.headset.fov[1] = {-0.6f, 0.7f, 0.65f, -0.75f};
    options.validation = true;
    options.clear_colour = kClear;
    try {
      return std::make_unique<StereoRenderer>(options);
    } catch (const NoVulkanDevice& e) {
      skipped_ = e.what();
      return nullptr;
    }
  }

  static OpenXrSinkOptions sink_options(const HeadsetDescription& rendered) {
    OpenXrSinkOptions o;
    o.rendered = rendered;
    o.validation = true;
    return o;
  }

  static void expect_no_validation(const OpenXrSink& sink) {
    std::string log;
    for (const std::string& m : sink.validation_log())
      log += m + "\n";
    EXPECT_EQ(sink.validation_messages(), 0u) << log;
  }

  static void expect_no_validation(const StereoRenderer& r) {
    std::string log;
    for (const std::string& m : r.validation_log())
      log += m + "\n";
    EXPECT_EQ(r.validation_messages(), 0u) << log;
  }

  std::filesystem::path log_;
  std::string skipped_;
};

TEST_F(OpenXrSimTest, PresentsRenderedFramesWithTheirPosesAndEndsCleanly) {
  auto r = renderer();
  if (!r) GTEST_SKIP() << "no Vulkan device: " << skipped_;
  r->add_solid(sphere(70.0));
  const HeadsetDescription rendered = r->options().headset;
  constexpr int kFrames = 6;
  OpenXrSinkStats stats;
  std::vector<Tee::Sent> sent;
  {
    OpenXrSink sink(sink_options(rendered));
    EXPECT_EQ(sink.runtime_name(), "bisturi simulated headset");
    EXPECT_EQ(sink.headset().eye_width, 1024u);  // the runtime's recommendation
    EXPECT_EQ(sink.swapchain_format(), "VK_FORMAT_R8G8B8A8_SRGB");
    Tee tee(sink);
    r->set_sink(&tee);
    // The first frame is not shown (see below): the second is the first with the head moved.
    for (int i = 0; i < kFrames; ++i)
      r->render(anterior_pose(8.0 * std::max(0, i - 1)));
    r->flush();
    stats = sink.stats();
    sent = tee.submitted;
    EXPECT_EQ(sink.session_state(), "FOCUSED");
    EXPECT_TRUE(sink.presenting());
    expect_no_validation(sink);
  }
  expect_no_validation(*r);

  // The first frame comes while the session is only SYNCHRONIZED: the runtime asks not to render.
  EXPECT_EQ(stats.frames_consumed, static_cast<std::uint64_t>(kFrames));
  EXPECT_EQ(stats.frames_not_rendered, 1u);
  EXPECT_EQ(stats.frames_dropped, 0u);
  EXPECT_EQ(stats.frames_submitted, static_cast<std::uint64_t>(kFrames - 1));
  ASSERT_EQ(sent.size(), stats.frames_submitted);

  const auto log = read_log(log_);
  std::vector<nlohmann::json> shown;
  for (const auto& f : events(log, "frame")) {
    if (f["layers"] == 1) shown.push_back(f);
  }
  ASSERT_EQ(shown.size(), sent.size()) << "frames with a projection layer";
  for (std::size_t k = 0; k < shown.size(); ++k) {
    const auto& views = shown[k]["views"];
    ASSERT_EQ(views.size(), 2u);
    for (int e = 0; e < 2; ++e) {
      const auto& v = views[static_cast<std::size_t>(e)];
      // The very bytes the renderer produced reached the runtime's image.
      EXPECT_EQ(v["checksum"], sent[k].checksum[static_cast<std::size_t>(e)])
          << "frame " << k << " eye " << e;
      EXPECT_EQ(v["rect"], nlohmann::json({0, 0, kSize, kSize}));
      const ExpectedView want = expected_view(rendered, sent[k].pose, e);
      for (int c = 0; c < 3; ++c) {
        EXPECT_NEAR(v["position"][static_cast<std::size_t>(c)].get<double>(), want.position[c],
                    1e-6)
            << "frame " << k << " eye " << e << " axis " << c;
      }
      const glm::dquat got(v["orientation"][3].get<double>(), v["orientation"][0].get<double>(),
                           v["orientation"][1].get<double>(), v["orientation"][2].get<double>());
      EXPECT_NEAR(std::abs(glm::dot(got, want.orientation)), 1.0, 1e-6) << "frame " << k;
      const EyeFov& fov = rendered.fov[static_cast<std::size_t>(e)];
      EXPECT_FLOAT_EQ(v["fov"][0].get<float>(), fov.angle_left);
      EXPECT_FLOAT_EQ(v["fov"][1].get<float>(), fov.angle_right);
      EXPECT_FLOAT_EQ(v["fov"][2].get<float>(), fov.angle_up);
      EXPECT_FLOAT_EQ(v["fov"][3].get<float>(), fov.angle_down);
    }
    // The sphere fills the left eye's centre (reddish), the clear colour its corner (blue).
    const auto& centre = views[0]["centre_rgba"];
    EXPECT_EQ(centre,
              nlohmann::json(std::vector<int>(sent[k].centre.begin(), sent[k].centre.end())));
    EXPECT_GT(centre[0].get<int>(), centre[2].get<int>()) << "centre is not the sphere";
    EXPECT_LT(sent[k].corner[0], sent[k].corner[2]) << "corner is not the clear colour";
  }
  // The first shown frame: head at 300 mm anterior, facing posterior, superior up, so in LOCAL
  // the left eye is at (-0.032, 0, 0.3) with the identity orientation.
  const auto& first = shown[0]["views"][0];
  EXPECT_NEAR(first["position"][0].get<double>(), -0.032, 1e-6);
  EXPECT_NEAR(first["position"][1].get<double>(), 0.0, 1e-6);
  EXPECT_NEAR(first["position"][2].get<double>(), 0.3, 1e-6);
  EXPECT_NEAR(first["orientation"][3].get<double>(), 1.0, 1e-6);

  // Display times advance by whole display periods.
  const auto frames = events(log, "frame");
  const double period = 1e9 / 90.0;
  for (std::size_t i = 1; i < frames.size(); ++i) {
    const double step =
        frames[i]["display_time_ns"].get<double>() - frames[i - 1]["display_time_ns"].get<double>();
    EXPECT_GT(step, 0.99 * period);
    EXPECT_NEAR(step / period, std::round(step / period), 0.01);
  }

  // The session went through FOCUSED and ended the way the specification orders.
  std::vector<std::string> states;
  for (const auto& s : events(log, "state"))
    states.push_back(s["state"]);
  const std::vector<std::string> want = {
      "XR_SESSION_STATE_IDLE",         "XR_SESSION_STATE_READY",    "XR_SESSION_STATE_SYNCHRONIZED",
      "XR_SESSION_STATE_VISIBLE",      "XR_SESSION_STATE_FOCUSED",  "XR_SESSION_STATE_VISIBLE",
      "XR_SESSION_STATE_SYNCHRONIZED", "XR_SESSION_STATE_STOPPING", "XR_SESSION_STATE_IDLE",
      "XR_SESSION_STATE_EXITING"};
  EXPECT_EQ(states, want);
  ASSERT_EQ(events(log, "session_destroyed").size(), 1u);
  EXPECT_EQ(events(log, "session_destroyed")[0]["running"], false);
  EXPECT_EQ(events(log, "end_session").size(), 1u);
  EXPECT_EQ(events(log, "instance_destroyed").size(), 1u);
  EXPECT_EQ(log.back()["event"], "instance_destroyed");
}

TEST_F(OpenXrSimTest, BgraSwapchainsGetTheSameColours) {
  setenv("BISTURI_XR_SIM_FORMATS", "bgra_srgb", 1);
  auto r = renderer();
  if (!r) GTEST_SKIP() << "no Vulkan device: " << skipped_;
  r->add_solid(sphere(70.0));
  std::vector<Tee::Sent> sent;
  {
    OpenXrSink sink(sink_options(r->options().headset));
    EXPECT_EQ(sink.swapchain_format(), "VK_FORMAT_B8G8R8A8_SRGB");
    Tee tee(sink);
    r->set_sink(&tee);
    for (int i = 0; i < 3; ++i)
      r->render(anterior_pose(0.0));
    r->flush();
    sent = tee.submitted;
    expect_no_validation(sink);
  }
  expect_no_validation(*r);
  ASSERT_EQ(sent.size(), 2u);
  const auto log = read_log(log_);
  ASSERT_EQ(events(log, "swapchain").size(), 2u);
  EXPECT_EQ(events(log, "swapchain")[0]["format"], "B8G8R8A8_SRGB");
  std::size_t k = 0;
  for (const auto& f : events(log, "frame")) {
    if (f["layers"] != 1) continue;
    ASSERT_LT(k, sent.size());
    // The runtime reads its BGRA image back as RGBA: the same bytes the renderer made.
    EXPECT_EQ(f["views"][0]["checksum"], sent[k].checksum[0]);
    EXPECT_EQ(f["views"][1]["checksum"], sent[k].checksum[1]);
    ++k;
  }
  EXPECT_EQ(k, sent.size());
}

TEST_F(OpenXrSimTest, RuntimeWithoutAnSrgbFormatIsRefusedClearly) {
  setenv("BISTURI_XR_SIM_FORMATS", "rgba_unorm,rgba16f", 1);
  try {
    OpenXrSink sink;
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

TEST_F(OpenXrSimTest, RuntimeEndingTheSessionStopsPresentingWithoutFailing) {
  setenv("BISTURI_XR_SIM_EXIT_AFTER", "3", 1);  // the user quits after three frames
  std::vector<std::uint8_t> pixels;
  OpenXrSinkOptions options;
  options.validation = true;
  OpenXrSink sink(options);
  for (std::uint64_t i = 0; i < 8; ++i)
    sink.consume(synthetic_frame(pixels, 32, 32, i));
  const OpenXrSinkStats stats = sink.stats();
  EXPECT_EQ(stats.frames_not_rendered, 1u);
  EXPECT_EQ(stats.frames_submitted, 2u);
  EXPECT_EQ(stats.frames_dropped, 5u);
  EXPECT_FALSE(sink.presenting());
  EXPECT_EQ(sink.session_state(), "EXITING");
  EXPECT_NE(sink.stop_reason().find("EXITING"), std::string::npos) << sink.stop_reason();
  expect_no_validation(sink);
  const auto log = read_log(log_);
  EXPECT_EQ(events(log, "frame").size(), 3u);
  EXPECT_EQ(events(log, "end_session").size(), 1u);
  ASSERT_EQ(events(log, "request_exit").size(), 1u);
  EXPECT_EQ(events(log, "request_exit")[0]["by"], "user");
}

TEST_F(OpenXrSimTest, FrameSizesTheSwapchainsCannotTakeAreRefusedNamingBoth) {
  std::vector<std::uint8_t> pixels;
  {
    OpenXrSink sink;
    sink.consume(synthetic_frame(pixels, 64, 48, 0));
    try {
      sink.consume(synthetic_frame(pixels, 32, 32, 1));
      FAIL() << "a frame of another size was taken";
    } catch (const RenderError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("32x32"), std::string::npos) << what;
      EXPECT_NE(what.find("64x48"), std::string::npos) << what;
    }
  }
  OpenXrSink sink;
  try {
    sink.consume(synthetic_frame(pixels, 5000, 2, 0));
    FAIL() << "a frame wider than the runtime allows was taken";
  } catch (const RenderError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("5000x2"), std::string::npos) << what;
    EXPECT_NE(what.find("4096x4096"), std::string::npos) << what;
  }
}

TEST_F(OpenXrSimTest, WaitFramePacesToTheDisplayRate) {
  setenv("BISTURI_XR_SIM_HZ", "50", 1);
  std::vector<std::uint8_t> pixels;
  OpenXrSink sink;
  sink.consume(synthetic_frame(pixels, 16, 16, 0));
  const auto start = std::chrono::steady_clock::now();
  constexpr int kFrames = 10;
  for (int i = 1; i <= kFrames; ++i)
    sink.consume(synthetic_frame(pixels, 16, 16, static_cast<std::uint64_t>(i)));
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  // Ten frames at 50 Hz take ten periods of 20 ms (less the part of the first already gone).
  EXPECT_GT(ms, 170.0);
  EXPECT_EQ(sink.stats().frames_submitted, static_cast<std::uint64_t>(kFrames));
  EXPECT_GT(sink.stats().wait_frame_ms, 150.0);
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
