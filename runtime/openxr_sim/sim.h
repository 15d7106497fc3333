#pragma once
// A simulated OpenXR runtime (a headset stand-in for tests): the objects behind its handles and
// the helpers its entry points share. One application at a time, called from one thread, as the
// project's OpenXrSink does; handles are checked against the live objects
// (XR_ERROR_HANDLE_INVALID).

#include <vulkan/vulkan.h>
#define XR_USE_GRAPHICS_API_VULKAN 1
#define XR_USE_TIMESPEC 1
#include <openxr/openxr.h>
#include <openxr/openxr_platform.h>
#include <openxr/openxr_reflection.h>
#include <time.h>

#include <array>
#include <cstdint>
#include <deque>
#include <memory>
#include <string>
#include <vector>

#include "frame_log.h"

namespace bisturi::xrsim {

/// Read from the environment at xrCreateInstance (the test and the runtime share nothing else).
struct Config {
  /// BISTURI_XR_SIM_HZ. Not 90 by default: a sink that assumes 90 Hz reads the pacing wrongly.
  double display_hz = 72.0;
  std::uint32_t eye_width = 1024;  ///< BISTURI_XR_SIM_EYE_SIZE=WxH (recommended)
  std::uint32_t eye_height = 1024;
  std::uint32_t max_eye_size = 4096;
  std::string log_path;                 ///< BISTURI_XR_SIM_LOG: one JSON line per event
  std::string png_dir;                  ///< BISTURI_XR_SIM_PNG_DIR: eye images of each frame
  std::int64_t exit_after_frames = -1;  ///< BISTURI_XR_SIM_EXIT_AFTER: the user quits then
  std::vector<VkFormat> formats;        ///< BISTURI_XR_SIM_FORMATS=bgra_srgb,rgba_srgb,...
  /// Per-eye fields of view (radians: left, right, up, down): asymmetric, and different per eye
  /// (each eye sees more to its own side), so no fixed or symmetric frustum matches them.
  std::array<XrFovf, 2> fov{XrFovf{-0.872f, 0.698f, 0.785f, -0.890f},
                            XrFovf{-0.698f, 0.872f, 0.785f, -0.890f}};
  float ipd_m = 0.0634f;
  /// BISTURI_XR_SIM_STILL=1: the head stays at the origin of LOCAL, looking down -z.
  bool still_head = false;
  /// BISTURI_XR_SIM_INVALID_VIEWS=3,4,9: frames (counted by xrWaitFrame from 0) at which
  /// xrLocateViews reports no valid location (and wild poses, as a real runtime may).
  std::vector<std::uint64_t> invalid_view_frames;
  /// BISTURI_XR_SIM_LOSE_AFTER=N: after N ended frames the session is lost (LOSS_PENDING); the
  /// headset is back BISTURI_XR_SIM_LOST_MS (default 150) ms later (xrGetSystem fails until then).
  std::int64_t lose_after_frames = -1;
  double lost_ms = 150.0;
  /// BISTURI_XR_SIM_TRIGGER_FRAMES=A-B: the right controller's trigger is held from frame A to
  /// frame B (counted by xrWaitFrame), released otherwise.
  std::int64_t trigger_from = -1, trigger_to = -1;
  /// BISTURI_XR_SIM_LOSE_INSTANCE_AFTER=N: after N ended frames the runtime goes away for good
  /// (instance loss pending; every call then answers XR_ERROR_INSTANCE_LOST).
  std::int64_t lose_instance_after_frames = -1;
  static Config from_environment();
};

struct Session;
struct ActionSet;
struct Action;

struct Instance {
  Config config;
  std::string application;
  FrameLog log;
  bool vulkan2 = false;  ///< XR_KHR_vulkan_enable2 enabled
  std::deque<XrEventDataBuffer> events;
  VkInstance vk_instance = VK_NULL_HANDLE;  ///< made through xrCreateVulkanInstanceKHR
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  bool requirements_queried = false;
  bool convert_timespec = false;  ///< XR_KHR_convert_timespec_time enabled
  std::vector<VkDevice> devices;  ///< made through xrCreateVulkanDeviceKHR
  Session* session = nullptr;
  std::int64_t start_ns = 0;         ///< the head's motion is a function of time since this
  std::int64_t headset_back_ns = 0;  ///< after a session loss: xrGetSystem fails until then
  std::uint64_t sessions_created = 0;
  bool lost = false;               ///< the instance is lost: every call fails
  std::vector<std::string> paths;  ///< XrPath n is paths[n - 1]
  std::vector<ActionSet*> action_sets;
};

struct Action {
  ActionSet* set = nullptr;
  std::string name;
  XrActionType type = XR_ACTION_TYPE_BOOLEAN_INPUT;
  std::vector<XrPath> subactions;
  std::vector<std::string> bindings;  ///< suggested for the simple controller, e.g. ".../grip/pose"
};

struct ActionSet {
  Instance* instance = nullptr;
  std::string name;
  Session* attached_to = nullptr;  ///< the live session it is attached to
  bool ever_attached = false;      ///< once attached it is immutable (actions, bindings)
  std::vector<Action*> actions;
};

struct Swapchain {
  Session* session = nullptr;
  VkFormat format = VK_FORMAT_UNDEFINED;
  std::uint32_t width = 0, height = 0;
  std::uint32_t array_size = 1;
  XrSwapchainUsageFlags usage = 0;
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
  const Action* action = nullptr;  ///< an action space: the grip of the hand it is bound to
  XrPath subaction = XR_NULL_PATH;
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
  bool loss_pending = false;
  // Frame timing (XrTime: steady clock nanoseconds).
  std::int64_t period_ns = 0;
  std::int64_t next_display_ns = 0;
  bool frame_waited = false;
  bool frame_begun = false;
  bool should_render = false;
  std::int64_t predicted_display_ns = 0;
  std::uint64_t frames_ended = 0;
  std::uint64_t frames_waited = 0;
  std::vector<Swapchain*> swapchains;
  std::vector<Space*> spaces;
  bool actions_attached = false;
  bool synced = false;  ///< xrSyncActions was called while FOCUSED
  std::uint64_t synced_frame = 0;
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
/// The pose of `view` (-1: the head, i.e. the VIEW space; 0, 1: the eyes) in LOCAL at `time`,
/// and whether it is valid (the configured invalid frames are not).
XrPosef head_pose(const Instance& instance, std::int64_t time_ns, int view);
/// A reference space's origin in LOCAL (STAGE is 1.6 m lower, at the floor).
XrPosef space_origin(XrReferenceSpaceType type);
/// `pose` (in LOCAL) seen from a space whose origin in LOCAL is `origin`.
XrPosef relative_to(const XrPosef& origin, const XrPosef& pose);
/// The right controller's grip in LOCAL at `time`.
XrPosef grip_pose(const Instance& instance, std::int64_t time_ns);
/// Whether an action space's controller is tracked now (bound, and the session focused).
bool action_space_tracked(const Space& space);
/// Deletes an instance's action sets and actions.
void destroy_action_sets(Instance& instance);
/// Whether the instance is lost (the caller answers XR_ERROR_INSTANCE_LOST).
bool instance_lost(const Instance* instance);
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
/// Copies one layer of the swapchain's shown image into its readback buffer; false on a Vulkan
/// failure.
bool read_back(Swapchain& swapchain, std::uint32_t image, std::uint32_t layer);
void destroy_swapchain(Swapchain* swapchain);

}  // namespace bisturi::xrsim
