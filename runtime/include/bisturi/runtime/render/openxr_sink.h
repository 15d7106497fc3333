#pragma once
// The headset through OpenXR (XR_KHR_vulkan_enable2). Construction asks the loader for a runtime
// and a head-mounted system; when there is none (no runtime installed, XR_RUNTIME_JSON unset or
// naming nothing, no headset, no usable swapchain format or device) it throws XrUnavailable with
// the reason, which the session catches to fall back to the headless sink.
//
// One device: the Vulkan instance and device are made through the runtime
// (xrCreateVulkanInstanceKHR / xrCreateVulkanDeviceKHR, on the physical device it names), and a
// StereoRenderer made on this sink draws its multiview pass straight into the runtime's swapchain
// (one swapchain, two layers: left, right); no pixel crosses the CPU.
//
// The frame loop is the runtime's: begin_frame() polls the session's events (and walks the
// lifecycle: begins the session at READY, ends it at STOPPING, recreates it after a loss when the
// headset is back), waits with xrWaitFrame (the runtime paces the loop to its display), begins
// the frame and locates both views at the predicted display time; the frame is rendered with
// exactly those views and end_frame() submits them, the same poses and fields of view, in the
// projection layer. Views whose location is not valid are never used: the frame reuses the last
// valid views (counted), or, before any, is submitted without a layer.
//
// Poses: the project's world is LPS millimetres (x left, y posterior, z superior); OpenXR's
// reference spaces are metres with y up. The world is turned so that superior is up (+y),
// anterior faces the viewer (+z) and the patient's left is +x (a viewer facing the patient sees
// its left on their right), and placed so that the operating field's centre (a world point)
// sits at a point of the reference space (OpenXrSinkOptions::field_*).

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/runtime/render/frame_sink.h"
#include "bisturi/runtime/render/headset.h"

namespace bisturi::render {

struct OpenXrSinkOptions {
  std::string application_name = "bisturi";
  /// VK_LAYER_KHRONOS_validation on the Vulkan instance made through the runtime (the renderer
  /// on this sink draws there; messages are counted).
  bool validation = false;
  /// STAGE (floor-level origin) instead of LOCAL when the runtime offers it.
  bool stage_space = false;
  /// Size of each eye's image; 0: the runtime's recommendation.
  std::uint32_t eye_width = 0, eye_height = 0;
  /// The world point (mm) at the operating field's centre...
  glm::dvec3 field_centre_mm{0.0};
  /// ...and where it sits in the reference space (metres, y up, -z ahead of the origin). LOCAL's
  /// origin is the head at the start: 0.35 m below the eyes, 0.45 m ahead.
  glm::dvec3 field_position_m{0.0, -0.35, -0.45};
  /// Track the right hand's controller (the Khronos simple controller's bindings, which every
  /// runtime maps): its grip pose and trigger in each frame, its vibration (vibrate).
  bool controller = false;
};

/// The right hand's controller as the runtime tracks it (OpenXrSinkOptions::controller).
struct ControllerState {
  bool active = false;      ///< bound, and located this frame (input goes to a focused session)
  glm::dvec3 grip_mm{0.0};  ///< the grip in the world, at the frame's display time
  /// The grip's frame to the world (OpenXR's grip frame: -z along the closed hand's axis).
  glm::dquat grip_orientation{1.0, 0.0, 0.0, 0.0};
  float trigger = 0.0f;  ///< 0 released .. 1 pulled
  PoseClock::time_point sample_time{};
};

/// A session state the runtime reported, and when (the event's time, on PoseClock).
struct XrStateChange {
  std::string state;  ///< "FOCUSED" (OpenXR's name without its prefix)
  PoseClock::time_point time{};
};

struct OpenXrSinkStats {
  std::uint64_t frames_begun = 0;          ///< xrWaitFrame + xrBeginFrame
  std::uint64_t frames_submitted = 0;      ///< xrEndFrame with the projection layer
  std::uint64_t frames_not_rendered = 0;   ///< the runtime said shouldRender = false
  std::uint64_t frames_without_views = 0;  ///< no valid views yet: submitted without a layer
  /// Frames whose views the runtime did not locate validly (the last valid ones were used).
  std::uint64_t invalid_view_locations = 0;
  /// Display refreshes the frame loop missed: gaps between successive predicted display times,
  /// in predicted display periods, less one.
  std::uint64_t dropped_frames = 0;
  double wait_frame_ms = 0.0;  ///< total time in xrWaitFrame (the runtime's pacing)
  /// xrWaitFrame's predicted display period: the last one, the least and the most seen (ns).
  std::int64_t display_period_ns = 0;
  std::int64_t min_display_period_ns = 0, max_display_period_ns = 0;
  std::uint64_t sessions_lost = 0;       ///< LOSS_PENDING, or a call answered SESSION_LOST
  std::uint64_t sessions_recreated = 0;  ///< made again once the headset was back
  std::uint64_t vibrations = 0;          ///< xrApplyHapticFeedback calls the runtime took
};

/// One frame of the runtime's loop (see begin_frame).
struct HeadsetFrame {
  bool began = false;                ///< xrBeginFrame was called: end_frame must follow
  bool should_render = false;        ///< render with `eyes`, then end_frame(frame, true)
  bool views_valid = false;          ///< located validly for this frame (else: the last valid ones)
  std::int64_t display_time_ns = 0;  ///< the predicted display time (XrTime)
  std::int64_t display_period_ns = 0;
  /// The head (the VIEW space) at the display time, in the world; sample_time: when it was
  /// located, display_time: the predicted display time.
  HeadPose head;
  std::array<EyePose, 2> eyes{};  ///< in the world, with the runtime's fields of view
  ControllerState controller;     ///< with OpenXrSinkOptions::controller
};

class OpenXrSink : public FrameSink {
 public:
  /// Throws XrUnavailable when no OpenXR runtime or headset can be used.
  explicit OpenXrSink(const std::string& application_name = "bisturi");
  explicit OpenXrSink(const OpenXrSinkOptions& options);
  ~OpenXrSink() override;
  OpenXrSink(const OpenXrSink&) = delete;
  OpenXrSink& operator=(const OpenXrSink&) = delete;

  /// Waits for the runtime's next frame (see the top of this file). When no session runs (not
  /// ready yet, lost and waiting for the headset, or stopped) it waits a little and returns a
  /// frame with began = false. Throws RenderError on a failure the runtime did not explain.
  HeadsetFrame begin_frame();
  /// Ends `frame`: releases the swapchain image the renderer drew into and submits the layer
  /// when `rendered` (the frame's views), or no layer.
  void end_frame(const HeadsetFrame& frame, bool rendered);

  /// Vibrates the right controller (a contact cue): amplitude 0..1 for `duration_s` (0: the
  /// shortest the runtime has). False when there is no controller to vibrate (not asked for,
  /// not bound, the session not focused). Throws RenderError on an amplitude outside 0..1.
  bool vibrate(float amplitude, double duration_s);
  /// Fault injection: the next swapchain image wait blocks for `duration` before the runtime's,
  /// as a compositor that holds on to its images makes it. The frame thread's.
  void stall_next_image_wait(std::chrono::nanoseconds duration);

  /// Ends the session the way the specification asks (xrRequestExitSession, xrEndSession at
  /// STOPPING, until EXITING), so that its last states are in state_changes(); the destructor
  /// does it too. Nothing is presented after.
  void finish();

  /// The renderer hands finished frames here (for their timing; there are no pixels to take).
  void consume(const StereoFrame& frame) override;
  [[nodiscard]] bool wants_pixels(std::uint64_t /*index*/) const override { return false; }

  /// The headset as the runtime describes it (recommended resolution per eye, its views'
  /// fields of view once located).
  [[nodiscard]] const HeadsetDescription& headset() const;
  [[nodiscard]] const std::string& runtime_name() const;
  [[nodiscard]] OpenXrSinkStats stats() const;
  /// The last session state the runtime reported, e.g. "FOCUSED" (OpenXR's name without prefix).
  [[nodiscard]] std::string session_state() const;
  /// Every state change so far, in order.
  [[nodiscard]] const std::vector<XrStateChange>& state_changes() const;
  /// "LOCAL" or "STAGE".
  [[nodiscard]] std::string reference_space() const;
  /// True while frames reach the headset (session visible, not told to exit).
  [[nodiscard]] bool presenting() const;
  /// True once the sink will not present again (the user exited, the runtime went away).
  [[nodiscard]] bool stopped() const;
  /// Why presenting stopped for good; empty while it has not.
  [[nodiscard]] const std::string& stop_reason() const;
  /// The swapchain format chosen, e.g. "VK_FORMAT_R8G8B8A8_SRGB".
  [[nodiscard]] std::string swapchain_format() const;
  /// Validation-layer messages on the shared device (0 without OpenXrSinkOptions::validation).
  [[nodiscard]] std::size_t validation_messages() const;
  [[nodiscard]] std::vector<std::string> validation_log() const;

  /// World (mm) to the reference space (m) and back, as the sink places the scene.
  [[nodiscard]] glm::dvec3 to_reference_m(const glm::dvec3& world_mm) const;

 private:
  friend struct OpenXrSinkAccess;
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bisturi::render
