#pragma once
// The OpenXR sink's state, shared by openxr_sink.cpp (instance, session, frame loop) and
// openxr_sink_vulkan.cpp (the sink's Vulkan device, swapchain images and the upload).

#include <vulkan/vulkan.h>
#define XR_USE_GRAPHICS_API_VULKAN 1
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

#include "bisturi/runtime/render/errors.h"
#include "vulkan_context.h"

#include "bisturi/runtime/render/openxr_sink.h"

namespace bisturi::render::xr_detail {

inline constexpr const char* kVulkanExtension = XR_KHR_VULKAN_ENABLE2_EXTENSION_NAME;
inline const std::string kFallback = "; frames can go to the headless (PNG) sink instead";

/// An XrResult as text (the runtime's name for it when an instance exists).
std::string xr_result(XrInstance instance, XrResult result);

/// Validation-layer messages on the sink's device, counted (never printed).
struct ValidationLog {
  std::atomic<std::size_t> messages{0};
  mutable std::mutex mutex;
  std::vector<std::string> lines;
};

/// The debug-utils callback: counts and keeps (never prints) the validation layer's messages.
VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                             VkDebugUtilsMessageTypeFlagsEXT types,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data,
                                             void* user);

}  // namespace bisturi::render::xr_detail

namespace bisturi::render {

using xr_detail::kFallback;
using xr_detail::kVulkanExtension;
using xr_detail::on_validation;
using xr_detail::ValidationLog;
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

  // The sink's own Vulkan device, made through the runtime (it may need extensions of its own).
  // Frames arrive as CPU pixels from the renderer, which owns a separate device; they are
  // uploaded through a staging buffer. Rendering straight into the swapchains on one shared
  // device (no CPU round trip) is future work.
  VkInstance vk_instance = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger = VK_NULL_HANDLE;
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer commands = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  ValidationLog validation;

  XrSession session = XR_NULL_HANDLE;
  XrSpace space = XR_NULL_HANDLE;
  XrSessionState state = XR_SESSION_STATE_UNKNOWN;
  bool running = false;
  bool stopped = false;
  std::string stop_reason;
  std::int64_t format = 0;
  bool bgra = false;

  struct Eye {
    XrSwapchain swapchain = XR_NULL_HANDLE;
    std::vector<VkImage> images;
  };
  std::array<Eye, 2> eyes;
  std::uint32_t width = 0, height = 0;  ///< of the swapchains (0: not made yet)
  VkBuffer staging = VK_NULL_HANDLE;    ///< both eyes, left then right
  VkDeviceMemory staging_memory = VK_NULL_HANDLE;
  std::uint8_t* staging_bytes = nullptr;
  OpenXrSinkStats stats;

  ~Impl() { release(); }

  [[noreturn]] void unavailable(const std::string& what, XrResult r) const {
    throw XrUnavailable("the OpenXR runtime " + runtime + " could not be used (" + what + ": " +
                        xr_result(instance, r) + ")" + kFallback);
  }
  void xr_setup(XrResult r, const char* what) const {
    if (XR_FAILED(r)) unavailable(what, r);
  }
  void xr_frame(XrResult r, const char* what) const {
    if (XR_FAILED(r)) {
      throw RenderError(std::string("OpenXR ") + what + " failed: " + xr_result(instance, r));
    }
  }

  void create_instance();
  void describe_system();
  void create_vulkan();
  void create_session();
  void choose_format();
  void poll_events();
  void on_state(XrSessionState next);
  void stop(std::string reason);
  void make_swapchains(std::uint32_t w, std::uint32_t h);
  void upload(const StereoFrame& frame);
  void end_frame(XrTime display_time, const StereoFrame* frame);
  std::uint32_t memory_type(std::uint32_t bits, VkMemoryPropertyFlags flags) const;
  void release();
};

}  // namespace bisturi::render
