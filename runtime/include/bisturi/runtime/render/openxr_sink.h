#pragma once
// The headset sink through OpenXR (XR_KHR_vulkan_enable2). Construction asks the loader for a
// runtime and a head-mounted system; when there is none (no runtime installed, XR_RUNTIME_JSON
// unset or naming nothing, no headset, no usable swapchain format) it throws XrUnavailable with
// the reason, which the session catches to fall back to the headless sink.
//
// Frames arrive as finished CPU pixels (StereoFrame) and are uploaded into the runtime's
// swapchains on a Vulkan device the runtime picks; each is submitted with the pose and field of
// view it was rendered for. Swapchains are made at the first frame, at the frame's eye size.
//
// Poses: the project's world is LPS millimetres (x left, y posterior, z superior); OpenXR's LOCAL
// space is metres with y up. The sink maps world to LOCAL by a fixed rotation, superior -> +y,
// anterior -> +z, patient's left -> +x (a viewer facing the patient sees its left on their right),
// and divides by 1000: xr = (x, z, -y) / 1000. The head frame is already OpenXR's view frame
// (headset.h), so a view's orientation is that rotation times the head's orientation.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "bisturi/runtime/render/frame_sink.h"
#include "bisturi/runtime/render/headset.h"

namespace bisturi::render {

struct OpenXrSinkOptions {
  std::string application_name = "bisturi";
  /// The eyes the frames were rendered for (IPD and per-eye field of view): each submitted view
  /// carries the eye's pose and fov from here, so they must match the renderer's headset.
  HeadsetDescription rendered;
  /// VK_LAYER_KHRONOS_validation on the sink's own Vulkan instance (messages are counted).
  bool validation = false;
  /// STAGE (floor-level origin) instead of LOCAL when the runtime offers it.
  bool stage_space = false;
};

struct OpenXrSinkStats {
  std::uint64_t frames_consumed = 0;
  std::uint64_t frames_submitted = 0;     ///< xrEndFrame with the projection layer
  std::uint64_t frames_not_rendered = 0;  ///< the runtime said shouldRender = false
  std::uint64_t frames_dropped = 0;       ///< no running session (not ready yet, or stopped)
  double wait_frame_ms = 0.0;             ///< total time in xrWaitFrame (the runtime's pacing)
  double upload_ms = 0.0;                 ///< total time staging, copying and releasing both eyes
};

class OpenXrSink : public FrameSink {
 public:
  /// Throws XrUnavailable when no OpenXR runtime or headset can be used.
  explicit OpenXrSink(const std::string& application_name = "bisturi");
  explicit OpenXrSink(const OpenXrSinkOptions& options);
  ~OpenXrSink() override;
  OpenXrSink(const OpenXrSink&) = delete;
  OpenXrSink& operator=(const OpenXrSink&) = delete;

  /// Presents the frame when the session runs and the runtime wants frames; throws RenderError
  /// when the frame's eye size changes or exceeds what the runtime allows (both sizes named).
  void consume(const StereoFrame& frame) override;

  /// The headset as the runtime describes it (recommended resolution per eye).
  [[nodiscard]] const HeadsetDescription& headset() const;
  [[nodiscard]] const std::string& runtime_name() const;
  [[nodiscard]] OpenXrSinkStats stats() const;
  /// The last session state the runtime reported, e.g. "FOCUSED" (OpenXR's name without prefix).
  [[nodiscard]] std::string session_state() const;
  /// True while frames reach the headset (session running, not told to exit).
  [[nodiscard]] bool presenting() const;
  /// Why presenting stopped for good (the runtime asked to exit, or the session is being lost);
  /// empty while it has not.
  [[nodiscard]] const std::string& stop_reason() const;
  /// The swapchain format chosen, e.g. "VK_FORMAT_R8G8B8A8_SRGB".
  [[nodiscard]] std::string swapchain_format() const;
  /// Validation-layer messages on the sink's device (0 without OpenXrSinkOptions::validation).
  [[nodiscard]] std::size_t validation_messages() const;
  [[nodiscard]] std::vector<std::string> validation_log() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bisturi::render
