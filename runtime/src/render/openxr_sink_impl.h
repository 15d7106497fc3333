#pragma once
// The OpenXR sink's state, shared by openxr_sink.cpp (instance, session, lifecycle),
// openxr_sink_frame.cpp (the frame loop, views and layers) and openxr_sink_vulkan.cpp (the
// Vulkan instance and device made through the runtime, the swapchain), and with the renderer that
// draws into the swapchain (OpenXrSinkAccess).

#include <vulkan/vulkan.h>
#define XR_USE_GRAPHICS_API_VULKAN 1
#define XR_USE_TIMESPEC 1
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>
#include <time.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <memory>
#include <mutex>
#include <thread>
#include <vector>

#include <glm/gtc/quaternion.hpp>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "vulkan_context.h"

namespace bisturi::render::xr_detail {

inline constexpr const char* kVulkanExtension = XR_KHR_VULKAN_ENABLE2_EXTENSION_NAME;
inline constexpr const char* kTimespecExtension = XR_KHR_CONVERT_TIMESPEC_TIME_EXTENSION_NAME;
inline const std::string kFallback = "; frames can go to the headless (PNG) sink instead";

/// An XrResult as text (the runtime's name for it when an instance exists).
std::string xr_result(XrInstance instance, XrResult result);
const char* state_name(XrSessionState state);

}  // namespace bisturi::render::xr_detail

namespace bisturi::render {

using xr_detail::kFallback;
using xr_detail::kTimespecExtension;
using xr_detail::kVulkanExtension;
using xr_detail::xr_result;

struct OpenXrSink::Impl {
  OpenXrSinkOptions options;
  XrInstance instance = XR_NULL_HANDLE;
  XrSystemId system = XR_NULL_SYSTEM_ID;
  HeadsetDescription headset;
  std::string runtime;
  std::uint32_t max_width = 0, max_height = 0;

  PFN_xrGetVulkanGraphicsRequirements2KHR get_requirements = nullptr;
  PFN_xrCreateVulkanInstanceKHR create_vk_instance = nullptr;
  PFN_xrGetVulkanGraphicsDevice2KHR get_vk_device = nullptr;
  PFN_xrCreateVulkanDeviceKHR create_vk_device = nullptr;
  PFN_xrConvertTimeToTimespecTimeKHR time_to_timespec = nullptr;  ///< null: not offered
  std::uint32_t vk_api_max = 0;

  /// The one Vulkan device: made through the runtime, shared with the renderer on this sink.
  std::shared_ptr<vk::Context> context;

  XrSession session = XR_NULL_HANDLE;
  XrSpace space = XR_NULL_HANDLE;       ///< LOCAL or STAGE
  XrSpace view_space = XR_NULL_HANDLE;  ///< the head
  XrReferenceSpaceType space_type = XR_REFERENCE_SPACE_TYPE_LOCAL;
  XrSessionState state = XR_SESSION_STATE_UNKNOWN;
  /// An injected stall: the next image wait is held this long first (0: none).
  std::chrono::nanoseconds stall_next_image_wait{0};
  bool running = false;
  bool stopped = false;
  bool lost = false;  ///< the session was lost: waiting for the headset to make a new one
  PoseClock::time_point next_system_try{};
  std::string stop_reason;
  std::vector<XrStateChange> changes;
  std::int64_t format = 0;
  VkFormat view_format = VK_FORMAT_UNDEFINED;  ///< the UNORM twin the renderer draws through

  // The swapchain: one two-layer image per slot (left eye layer 0, right eye layer 1).
  XrSwapchain swapchain = XR_NULL_HANDLE;
  std::vector<VkImage> images;
  std::uint32_t width = 0, height = 0;
  std::uint64_t swapchain_generation = 0;  ///< bumped whenever the images change
  bool image_acquired = false;
  std::uint32_t acquired_index = 0;
  /// Called before the swapchain's images go away (the renderer drops its views of them).
  std::function<void()> before_swapchain_destroyed;

  // The right controller (OpenXrSinkOptions::controller): actions made once per instance,
  // attached and given a grip space in each session.
  XrActionSet action_set = XR_NULL_HANDLE;
  XrAction grip_action = XR_NULL_HANDLE, trigger_action = XR_NULL_HANDLE,
           haptic_action = XR_NULL_HANDLE;
  XrPath right_hand = XR_NULL_PATH;
  XrSpace grip_space = XR_NULL_HANDLE;

  // The frame loop.
  std::int64_t last_display_ns = 0;
  bool have_views = false;  ///< some valid views were located: `last_*` hold them
  std::array<XrView, 2> last_views{};
  glm::dvec3 last_head_m{0.0};  ///< the head in the reference space at the last valid location
  glm::dquat last_head_orientation{1.0, 0.0, 0.0, 0.0};
  PoseClock::time_point last_sample{};
  OpenXrSinkStats stats;
  /// BISTURI_XR_VIEWS_LOG: every xrLocateViews answer as the runtime gave it, one JSON line per
  /// frame, to compare with the layers an API-dump layer records (development aid).
  std::FILE* views_log = nullptr;

  ~Impl() { release(); }

  [[noreturn]] void unavailable(const std::string& what, XrResult r) const {
    throw XrUnavailable("the OpenXR runtime " + runtime + " could not be used (" + what + ": " +
                        xr_result(instance, r) + ")" + kFallback);
  }
  void xr_setup(XrResult r, const char* what) const {
    if (XR_FAILED(r)) unavailable(what, r);
  }
  /// A frame call's result: true when it succeeded; false when the session or the instance was
  /// lost (handled: the loss is recorded); throws RenderError otherwise.
  bool xr_frame(XrResult r, const char* what);

  // openxr_sink.cpp
  void create_instance();
  void describe_system();
  void create_session();
  void choose_format();
  void poll_events();
  void on_state(XrSessionState next, XrTime time);
  void stop(std::string reason);
  void lose_session();
  void try_recreate();
  void destroy_session();
  PoseClock::time_point to_pose_clock(XrTime time) const;
  XrTime now_xr() const;

  // openxr_sink_frame.cpp
  /// A position (m) and an orientation in the reference space, in the world (mm).
  glm::dvec3 world_position(const glm::dvec3& reference_m) const;
  glm::dquat world_orientation(const glm::dquat& reference) const;
  HeadsetFrame begin_frame();
  void end_frame(const HeadsetFrame& frame, bool rendered);
  std::uint32_t acquire_image();

  // openxr_sink_input.cpp
  void create_input();
  void attach_input();
  ControllerState read_controller(XrTime display_time);
  bool vibrate(float amplitude, double duration_s);

  // openxr_sink_vulkan.cpp
  void create_vulkan();
  void make_swapchain(std::uint32_t w, std::uint32_t h);
  void destroy_swapchain();
  void finish();
  void release();
};

/// The renderer's way in: the shared device, the swapchain's images and their acquisition.
struct OpenXrSinkAccess {
  using Impl = OpenXrSink::Impl;
  static Impl& of(OpenXrSink& sink) { return *sink.impl_; }
};

}  // namespace bisturi::render
