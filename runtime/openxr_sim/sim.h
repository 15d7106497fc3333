#pragma once
// A simulated OpenXR runtime (a headset stand-in for tests): the objects behind its handles and
// the helpers its entry points share. One application at a time, called from one thread, as the
// project's OpenXrSink does; handles are checked against the live objects
// (XR_ERROR_HANDLE_INVALID).

#include <vulkan/vulkan.h>
#define XR_USE_GRAPHICS_API_VULKAN 1
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>
#include <openxr/openxr_reflection.h>

#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "frame_log.h"

namespace bisturi::xrsim {

/// Read from the environment at xrCreateInstance (the test and the runtime share nothing else).
struct Config {
  double display_hz = 90.0;        ///< BISTURI_XR_SIM_HZ
  std::uint32_t eye_width = 1024;  ///< BISTURI_XR_SIM_EYE_SIZE=WxH (recommended)
  std::uint32_t eye_height = 1024;
  std::uint32_t max_eye_size = 4096;
  std::string log_path;                 ///< BISTURI_XR_SIM_LOG: one JSON line per event
  std::string png_dir;                  ///< BISTURI_XR_SIM_PNG_DIR: eye images of each frame
  std::int64_t exit_after_frames = -1;  ///< BISTURI_XR_SIM_EXIT_AFTER: the user quits then
  std::vector<VkFormat> formats;        ///< BISTURI_XR_SIM_FORMATS=bgra_srgb,rgba_srgb,...
  static Config from_environment();
};

struct Session;

struct Instance {
  Config config;
  std::string application;
  FrameLog log;
  bool vulkan2 = false;  ///< XR_KHR_vulkan_enable2 enabled
  std::deque<XrEventDataBuffer> events;
  VkInstance vk_instance = VK_NULL_HANDLE;  ///< made through xrCreateVulkanInstanceKHR
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  bool requirements_queried = false;
  Session* session = nullptr;
};

struct Swapchain {
  Session* session = nullptr;
  VkFormat format = VK_FORMAT_UNDEFINED;
  std::uint32_t width = 0, height = 0;
  std::vector<VkImage> images;
  std::vector<VkDeviceMemory> memory;
  std::deque<std::uint32_t> acquired;  ///< in acquisition order
  std::uint32_t next_image = 0;
  bool waited = false;
  std::int64_t released = -1;  ///< the image a layer shows
  VkBuffer readback = VK_NULL_HANDLE;
  VkDeviceMemory readback_memory = VK_NULL_HANDLE;
  void* mapped = nullptr;
};

struct Space {
  Session* session = nullptr;
  XrReferenceSpaceType type = XR_REFERENCE_SPACE_TYPE_LOCAL;
};

struct Session {
  Instance* instance = nullptr;
  VkDevice device = VK_NULL_HANDLE;
  VkQueue queue = VK_NULL_HANDLE;
  std::uint32_t queue_family = 0;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkCommandBuffer commands = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  XrSessionState state = XR_SESSION_STATE_UNKNOWN;
  bool running = false;
  bool exit_requested = false;
  // Frame timing (XrTime: steady clock nanoseconds).
  std::int64_t period_ns = 0;
  std::int64_t next_display_ns = 0;
  bool frame_waited = false;
  bool frame_begun = false;
  bool should_render = false;
  std::int64_t predicted_display_ns = 0;
  std::uint64_t frames_ended = 0;
  std::vector<Swapchain*> swapchains;
  std::vector<Space*> spaces;
};

// --- Handles ---
bool live(const void* object);
void track(const void* object);
void untrack(const void* object);
template <typename T, typename H>
T* object(H handle) {
  void* p = reinterpret_cast<void*>(handle);
  return live(p) ? static_cast<T*>(p) : nullptr;
}
template <typename H, typename T>
H handle(T* object) {
  return reinterpret_cast<H>(object);
}

// --- Shared helpers ---
std::int64_t now_ns();
const char* state_name(XrSessionState state);
const char* format_name(VkFormat format);
/// Queues the state-change event, records it in the log and makes it the session's state.
void set_state(Session& session, XrSessionState state);
/// From a running state down to STOPPING, one state at a time as the specification orders them.
void begin_stopping(Session& session);
/// Records and submits `record`'s commands on the application's queue and waits for them.
bool run_commands(Session& session, void (*record)(VkCommandBuffer, void*), void* user);
std::uint32_t memory_type(VkPhysicalDevice physical, std::uint32_t bits,
                          VkMemoryPropertyFlags flags);
/// Copies the swapchain's shown image into its readback buffer; false on a Vulkan failure.
bool read_back(Swapchain& swapchain, std::uint32_t image);
void destroy_swapchain(Swapchain* swapchain);

}  // namespace bisturi::xrsim
