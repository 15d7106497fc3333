#pragma once
// What a session's headset did, as the OpenXR runtime saw it: the runtime, the reference space,
// the display's rate from xrWaitFrame's predicted display period, refreshes missed against that
// period, views the runtime could not locate, every session state change, lost and recreated
// sessions, and whether frames crossed the CPU on their way to the headset.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace bisturi::runtime {

struct HeadsetStateChange {
  std::string state;    ///< OpenXR's name without its prefix, e.g. "FOCUSED"
  double time_s = 0.0;  ///< the event's time, since the session started
};

struct HeadsetReport {
  std::string sink;             ///< "openxr", or empty when no headset was used
  std::string runtime;          ///< the runtime's name
  std::string reference_space;  ///< "LOCAL" or "STAGE"
  std::string swapchain_format;
  std::uint32_t eye_width = 0, eye_height = 0;  ///< of the swapchain's images
  /// From xrWaitFrame's predictedDisplayPeriod (the last one; least and most seen).
  double display_period_ms = 0.0;
  double min_display_period_ms = 0.0, max_display_period_ms = 0.0;
  double display_hz = 0.0;  ///< 1 / display_period_ms
  std::uint64_t frames_begun = 0;
  std::uint64_t frames_submitted = 0;      ///< with the projection layer
  std::uint64_t frames_not_rendered = 0;   ///< the runtime said shouldRender = false
  std::uint64_t frames_without_views = 0;  ///< before any valid view location: no layer
  /// Display refreshes without a new frame: gaps between predicted display times, in periods.
  std::uint64_t dropped_frames = 0;
  /// Frames whose views were not validly located (the last valid views were used instead).
  std::uint64_t invalid_view_locations = 0;
  std::vector<HeadsetStateChange> states;
  std::uint64_t sessions_lost = 0;
  std::uint64_t sessions_recreated = 0;
  /// Haptic ticks whose forces were held at zero because the headset showed nothing.
  std::uint64_t ticks_without_display = 0;
  /// Times the renderer stopped coming round for longer than display_timeout_ms (a hung frame,
  /// a stalled swapchain): the forces were held at zero until it came back.
  std::uint64_t display_stalls = 0;
  double display_timeout_ms = 0.0;
  bool shared_device = false;       ///< the renderer drew on the runtime's Vulkan device
  bool frames_crossed_cpu = false;  ///< any frame's pixels were read back to host memory
  std::uint64_t frames_read_back = 0;
  /// The fields of view of the last located views (radians: left, right, up, down per eye).
  std::array<std::array<float, 4>, 2> fov{};
  std::string stop_reason;  ///< why presenting ended early (the user exited, runtime gone)
  std::string note;         ///< e.g. that the scene's head tracker was not used for the views
};

/// The report as one JSON object (text).
std::string to_json(const HeadsetReport& report);

}  // namespace bisturi::runtime
