#include "bisturi/runtime/render/openxr_sink.h"

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

namespace bisturi::render {

namespace {

constexpr const char* kVulkanExtension = XR_KHR_VULKAN_ENABLE2_EXTENSION_NAME;
constexpr const char* kValidationLayer = "VK_LAYER_KHRONOS_validation";
const std::string kFallback = "; frames can go to the headless (PNG) sink instead";

std::string xr_result(XrInstance instance, XrResult result) {
  char text[XR_MAX_RESULT_STRING_SIZE] = {};
  if (instance != XR_NULL_HANDLE && xrResultToString(instance, result, text) == XR_SUCCESS) {
    return text;
  }
  switch (result) {
    case XR_ERROR_RUNTIME_UNAVAILABLE:
      return "XR_ERROR_RUNTIME_UNAVAILABLE";
    case XR_ERROR_RUNTIME_FAILURE:
      return "XR_ERROR_RUNTIME_FAILURE";
    case XR_ERROR_INSTANCE_LOST:
      return "XR_ERROR_INSTANCE_LOST";
    case XR_ERROR_FORM_FACTOR_UNAVAILABLE:
      return "XR_ERROR_FORM_FACTOR_UNAVAILABLE";
    case XR_ERROR_FORM_FACTOR_UNSUPPORTED:
      return "XR_ERROR_FORM_FACTOR_UNSUPPORTED";
    case XR_ERROR_EXTENSION_NOT_PRESENT:
      return "XR_ERROR_EXTENSION_NOT_PRESENT";
    default:
      return "XrResult " + std::to_string(static_cast<int>(result));
  }
}

/// The loader prints its errors to stderr unless XR_LOADER_DEBUG says otherwise, which on every
/// machine without a runtime repeats, in ten lines, what XrUnavailable already says. It reads the
/// variable once, at its first call: quiet it then, unless the user set it (XR_LOADER_DEBUG=error
/// or =all brings the loader's own diagnosis back).
void quiet_loader() {
  static std::once_flag once;
  std::call_once(once, [] { setenv("XR_LOADER_DEBUG", "none", 0); });
}

/// Why the loader found no runtime, as far as can be told from outside it.
std::string missing_runtime_reason() {
  const char* named = std::getenv("XR_RUNTIME_JSON");
  if (named != nullptr && *named != '\0') {
    std::error_code error;
    if (!std::filesystem::exists(named, error)) {
      return std::string("XR_RUNTIME_JSON names ") + named + ", which does not exist";
    }
    return std::string("the runtime that XR_RUNTIME_JSON names (") + named + ") did not load";
  }
  return "none is installed (no active_runtime.json), and XR_RUNTIME_JSON does not name one";
}

const char* state_name(XrSessionState state) {
  switch (state) {
    case XR_SESSION_STATE_IDLE:
      return "IDLE";
    case XR_SESSION_STATE_READY:
      return "READY";
    case XR_SESSION_STATE_SYNCHRONIZED:
      return "SYNCHRONIZED";
    case XR_SESSION_STATE_VISIBLE:
      return "VISIBLE";
    case XR_SESSION_STATE_FOCUSED:
      return "FOCUSED";
    case XR_SESSION_STATE_STOPPING:
      return "STOPPING";
    case XR_SESSION_STATE_LOSS_PENDING:
      return "LOSS_PENDING";
    case XR_SESSION_STATE_EXITING:
      return "EXITING";
    default:
      return "UNKNOWN";
  }
}

std::uint32_t vulkan_version(XrVersion v) {
  return VK_MAKE_API_VERSION(0, XR_VERSION_MAJOR(v), XR_VERSION_MINOR(v), 0);
}

/// World (LPS millimetres) to OpenXR LOCAL (metres, y up): a -90 degree turn about x, so that
/// superior is up and anterior is +z (see openxr_sink.h).
XrPosef xr_pose(const glm::dvec3& position_mm, const glm::dquat& orientation) {
  const double h = std::sqrt(0.5);
  const glm::dquat world_to_xr(h, -h, 0.0, 0.0);  // (w, x, y, z)
  const glm::dquat q = glm::normalize(world_to_xr * orientation);
  XrPosef pose;
  pose.orientation = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z),
                      static_cast<float>(q.w)};
  pose.position = {static_cast<float>(position_mm.x / 1000.0),
                   static_cast<float>(position_mm.z / 1000.0),
                   static_cast<float>(-position_mm.y / 1000.0)};
  return pose;
}

/// Validation-layer messages on the sink's device, counted (never printed).
struct ValidationLog {
  std::atomic<std::size_t> messages{0};
  mutable std::mutex mutex;
  std::vector<std::string> lines;
};

VKAPI_ATTR VkBool32 VKAPI_CALL on_validation(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                             VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                             const VkDebugUtilsMessengerCallbackDataEXT* data,
                                             void* user) {
  auto* log = static_cast<ValidationLog*>(user);
  ++log->messages;
  std::string text =
      (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) != 0 ? "error: " : "warning: ";
  text += data != nullptr && data->pMessage != nullptr ? data->pMessage : "(no message)";
  const std::lock_guard<std::mutex> lock(log->mutex);
  if (log->lines.size() < 100) log->lines.push_back(std::move(text));
  return VK_FALSE;
}

}  // namespace

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

namespace {

bool has_layer(const char* name) {
  std::uint32_t count = 0;
  if (vkEnumerateInstanceLayerProperties(&count, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  for (const VkLayerProperties& l : layers) {
    if (std::strcmp(l.layerName, name) == 0) return true;
  }
  return false;
}

void image_barrier(VkCommandBuffer commands, VkImage image, VkImageLayout from, VkImageLayout to,
                   VkAccessFlags src_access, VkAccessFlags dst_access,
                   VkPipelineStageFlags src_stage, VkPipelineStageFlags dst_stage) {
  VkImageMemoryBarrier b{};
  b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, 1};
  vkCmdPipelineBarrier(commands, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

}  // namespace

void OpenXrSink::Impl::create_instance() {
  quiet_loader();
  // The renderer's frames reach the headset through Vulkan: the runtime must offer
  // XR_KHR_vulkan_enable2.
  std::uint32_t count = 0;
  XrResult r = xrEnumerateInstanceExtensionProperties(nullptr, 0, &count, nullptr);
  if (XR_FAILED(r)) {
    throw XrUnavailable("no OpenXR runtime is available (" + xr_result(XR_NULL_HANDLE, r) +
                        "): " + missing_runtime_reason() + kFallback);
  }
  XrExtensionProperties blank_extension{};
  blank_extension.type = XR_TYPE_EXTENSION_PROPERTIES;
  std::vector<XrExtensionProperties> extensions(count, blank_extension);
  xrEnumerateInstanceExtensionProperties(nullptr, count, &count, extensions.data());
  bool vulkan = false;
  for (const XrExtensionProperties& e : extensions) {
    vulkan = vulkan || std::strcmp(e.extensionName, kVulkanExtension) == 0;
  }
  if (!vulkan) {
    throw XrUnavailable("the OpenXR runtime does not offer " + std::string(kVulkanExtension) +
                        kFallback);
  }
  XrInstanceCreateInfo info{};
  info.type = XR_TYPE_INSTANCE_CREATE_INFO;
  std::strncpy(info.applicationInfo.applicationName, options.application_name.c_str(),
               XR_MAX_APPLICATION_NAME_SIZE - 1);
  std::strncpy(info.applicationInfo.engineName, "bisturi", XR_MAX_ENGINE_NAME_SIZE - 1);
  info.applicationInfo.apiVersion = XR_CURRENT_API_VERSION;
  const char* enabled[] = {kVulkanExtension};
  info.enabledExtensionCount = 1;
  info.enabledExtensionNames = enabled;
  r = xrCreateInstance(&info, &instance);
  if (XR_FAILED(r)) {
    instance = XR_NULL_HANDLE;
    throw XrUnavailable("no OpenXR runtime is available (xrCreateInstance: " +
                        xr_result(XR_NULL_HANDLE, r) + ")" + kFallback);
  }
  XrInstanceProperties props{};
  props.type = XR_TYPE_INSTANCE_PROPERTIES;
  if (XR_SUCCEEDED(xrGetInstanceProperties(instance, &props))) runtime = props.runtimeName;
  const auto load = [&](const char* name, auto& function) {
    PFN_xrVoidFunction f = nullptr;
    xr_setup(xrGetInstanceProcAddr(instance, name, &f), name);
    function = reinterpret_cast<std::remove_reference_t<decltype(function)>>(f);
  };
  load("xrGetVulkanGraphicsRequirements2KHR", get_requirements);
  load("xrCreateVulkanInstanceKHR", create_vk_instance);
  load("xrGetVulkanGraphicsDevice2KHR", get_vk_device);
  load("xrCreateVulkanDeviceKHR", create_vk_device);
}

void OpenXrSink::Impl::describe_system() {
  XrSystemGetInfo info{};
  info.type = XR_TYPE_SYSTEM_GET_INFO;
  info.formFactor = XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY;
  const XrResult r = xrGetSystem(instance, &info, &system);
  if (XR_FAILED(r)) {
    throw XrUnavailable("the OpenXR runtime " + runtime + " has no headset (" +
                        xr_result(instance, r) + ")" + kFallback);
  }
  std::uint32_t views = 0;
  xr_setup(xrEnumerateViewConfigurationViews(
               instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &views, nullptr),
           "xrEnumerateViewConfigurationViews");
  if (views != 2) {
    throw XrUnavailable("the OpenXR runtime " + runtime + " offers " + std::to_string(views) +
                        " views for a stereo headset, not 2" + kFallback);
  }
  XrViewConfigurationView blank{};
  blank.type = XR_TYPE_VIEW_CONFIGURATION_VIEW;
  std::vector<XrViewConfigurationView> config(views, blank);
  xr_setup(
      xrEnumerateViewConfigurationViews(instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO,
                                        views, &views, config.data()),
      "xrEnumerateViewConfigurationViews");
  headset.eye_width = config[0].recommendedImageRectWidth;
  headset.eye_height = config[0].recommendedImageRectHeight;
  max_width = std::min(config[0].maxImageRectWidth, config[1].maxImageRectWidth);
  max_height = std::min(config[0].maxImageRectHeight, config[1].maxImageRectHeight);
  // The frames are opaque images: the headset must show them as they are.
  std::uint32_t modes = 0;
  xr_setup(xrEnumerateEnvironmentBlendModes(
               instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &modes, nullptr),
           "xrEnumerateEnvironmentBlendModes");
  std::vector<XrEnvironmentBlendMode> mode(modes);
  xr_setup(
      xrEnumerateEnvironmentBlendModes(instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO,
                                       modes, &modes, mode.data()),
      "xrEnumerateEnvironmentBlendModes");
  if (std::find(mode.begin(), mode.end(), XR_ENVIRONMENT_BLEND_MODE_OPAQUE) == mode.end()) {
    throw XrUnavailable("the OpenXR runtime " + runtime +
                        " has no opaque blend mode for the stereo view" + kFallback);
  }
}

void OpenXrSink::Impl::create_vulkan() {
  XrGraphicsRequirementsVulkan2KHR requirements{};
  requirements.type = XR_TYPE_GRAPHICS_REQUIREMENTS_VULKAN2_KHR;
  xr_setup(get_requirements(instance, system, &requirements),
           "xrGetVulkanGraphicsRequirements2KHR");
  std::uint32_t api = VK_API_VERSION_1_1;  // enough for copies; the runtime may ask for more
  api = std::max(api, vulkan_version(requirements.minApiVersionSupported));

  VkApplicationInfo app{};
  app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
  app.pApplicationName = options.application_name.c_str();
  app.pEngineName = "bisturi";
  app.apiVersion = api;
  std::vector<const char*> layers, extensions;
  VkDebugUtilsMessengerCreateInfoEXT messenger_info{};
  messenger_info.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
  messenger_info.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                                   VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  messenger_info.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                               VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  messenger_info.pfnUserCallback = on_validation;
  messenger_info.pUserData = &validation;
  if (options.validation) {
    if (!has_layer(kValidationLayer)) {
      throw RenderError(
          "Vulkan validation was asked for but VK_LAYER_KHRONOS_validation is not installed "
          "(Debian: vulkan-validationlayers)");
    }
    layers.push_back(kValidationLayer);
    extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
  }
  VkInstanceCreateInfo vk_info{};
  vk_info.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
  vk_info.pApplicationInfo = &app;
  vk_info.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  vk_info.ppEnabledLayerNames = layers.data();
  vk_info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  vk_info.ppEnabledExtensionNames = extensions.data();
  if (options.validation) vk_info.pNext = &messenger_info;
  XrVulkanInstanceCreateInfoKHR xr_info{};
  xr_info.type = XR_TYPE_VULKAN_INSTANCE_CREATE_INFO_KHR;
  xr_info.systemId = system;
  xr_info.pfnGetInstanceProcAddr = &vkGetInstanceProcAddr;
  xr_info.vulkanCreateInfo = &vk_info;
  VkResult vk_result = VK_SUCCESS;
  XrResult r = create_vk_instance(instance, &xr_info, &vk_instance, &vk_result);
  if (XR_FAILED(r) || vk_result != VK_SUCCESS) {
    vk_instance = VK_NULL_HANDLE;
    unavailable(
        std::string("xrCreateVulkanInstanceKHR, vkCreateInstance: ") + vk::result_name(vk_result),
        r);
  }
  if (options.validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(vk_instance, "vkCreateDebugUtilsMessengerEXT"));
    if (create == nullptr) throw RenderError("vkCreateDebugUtilsMessengerEXT is not available");
    vk::check(create(vk_instance, &messenger_info, nullptr, &messenger),
              "vkCreateDebugUtilsMessengerEXT");
  }

  XrVulkanGraphicsDeviceGetInfoKHR device_info{};
  device_info.type = XR_TYPE_VULKAN_GRAPHICS_DEVICE_GET_INFO_KHR;
  device_info.systemId = system;
  device_info.vulkanInstance = vk_instance;
  xr_setup(get_vk_device(instance, &device_info, &physical), "xrGetVulkanGraphicsDevice2KHR");
  std::uint32_t families = 0;
  vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, nullptr);
  std::vector<VkQueueFamilyProperties> family(families);
  vkGetPhysicalDeviceQueueFamilyProperties(physical, &families, family.data());
  queue_family = families;
  for (std::uint32_t f = 0; f < families && queue_family == families; ++f) {
    if ((family[f].queueFlags & VK_QUEUE_GRAPHICS_BIT) != 0) queue_family = f;
  }
  if (queue_family == families) {
    throw XrUnavailable("the Vulkan device the OpenXR runtime " + runtime +
                        " uses has no graphics queue" + kFallback);
  }
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo queue_info{};
  queue_info.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
  queue_info.queueFamilyIndex = queue_family;
  queue_info.queueCount = 1;
  queue_info.pQueuePriorities = &priority;
  VkDeviceCreateInfo device_create{};
  device_create.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
  device_create.queueCreateInfoCount = 1;
  device_create.pQueueCreateInfos = &queue_info;
  XrVulkanDeviceCreateInfoKHR xr_device{};
  xr_device.type = XR_TYPE_VULKAN_DEVICE_CREATE_INFO_KHR;
  xr_device.systemId = system;
  xr_device.pfnGetInstanceProcAddr = &vkGetInstanceProcAddr;
  xr_device.vulkanPhysicalDevice = physical;
  xr_device.vulkanCreateInfo = &device_create;
  r = create_vk_device(instance, &xr_device, &device, &vk_result);
  if (XR_FAILED(r) || vk_result != VK_SUCCESS) {
    device = VK_NULL_HANDLE;
    unavailable(
        std::string("xrCreateVulkanDeviceKHR, vkCreateDevice: ") + vk::result_name(vk_result), r);
  }
  vkGetDeviceQueue(device, queue_family, 0, &queue);
  VkCommandPoolCreateInfo pool_info{};
  pool_info.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
  pool_info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pool_info.queueFamilyIndex = queue_family;
  vk::check(vkCreateCommandPool(device, &pool_info, nullptr, &pool), "vkCreateCommandPool");
  VkCommandBufferAllocateInfo allocate{};
  allocate.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
  allocate.commandPool = pool;
  allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  allocate.commandBufferCount = 1;
  vk::check(vkAllocateCommandBuffers(device, &allocate, &commands), "vkAllocateCommandBuffers");
  VkFenceCreateInfo fence_info{};
  fence_info.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
  vk::check(vkCreateFence(device, &fence_info, nullptr, &fence), "vkCreateFence");
}

void OpenXrSink::Impl::create_session() {
  XrGraphicsBindingVulkan2KHR binding{};
  binding.type = XR_TYPE_GRAPHICS_BINDING_VULKAN2_KHR;
  binding.instance = vk_instance;
  binding.physicalDevice = physical;
  binding.device = device;
  binding.queueFamilyIndex = queue_family;
  binding.queueIndex = 0;
  XrSessionCreateInfo info{};
  info.type = XR_TYPE_SESSION_CREATE_INFO;
  info.next = &binding;
  info.systemId = system;
  xr_setup(xrCreateSession(instance, &info, &session), "xrCreateSession");

  XrReferenceSpaceType type = XR_REFERENCE_SPACE_TYPE_LOCAL;
  if (options.stage_space) {
    std::uint32_t count = 0;
    xr_setup(xrEnumerateReferenceSpaces(session, 0, &count, nullptr), "xrEnumerateReferenceSpaces");
    std::vector<XrReferenceSpaceType> spaces(count);
    xr_setup(xrEnumerateReferenceSpaces(session, count, &count, spaces.data()),
             "xrEnumerateReferenceSpaces");
    if (std::find(spaces.begin(), spaces.end(), XR_REFERENCE_SPACE_TYPE_STAGE) != spaces.end()) {
      type = XR_REFERENCE_SPACE_TYPE_STAGE;
    }
  }
  XrReferenceSpaceCreateInfo space_info{};
  space_info.type = XR_TYPE_REFERENCE_SPACE_CREATE_INFO;
  space_info.referenceSpaceType = type;
  space_info.poseInReferenceSpace.orientation.w = 1.0f;
  xr_setup(xrCreateReferenceSpace(session, &space_info, &space), "xrCreateReferenceSpace");
}

void OpenXrSink::Impl::choose_format() {
  std::uint32_t count = 0;
  xr_setup(xrEnumerateSwapchainFormats(session, 0, &count, nullptr), "xrEnumerateSwapchainFormats");
  std::vector<std::int64_t> formats(count);
  xr_setup(xrEnumerateSwapchainFormats(session, count, &count, formats.data()),
           "xrEnumerateSwapchainFormats");
  // The frames are sRGB-encoded RGBA8 bytes: copied as they are into an sRGB image they mean the
  // same colours. RGBA first (a plain copy), BGRA second (swizzled while staging).
  for (const VkFormat wanted : {VK_FORMAT_R8G8B8A8_SRGB, VK_FORMAT_B8G8R8A8_SRGB}) {
    if (std::find(formats.begin(), formats.end(), wanted) != formats.end()) {
      format = wanted;
      bgra = wanted == VK_FORMAT_B8G8R8A8_SRGB;
      return;
    }
  }
  std::string offered;
  for (const std::int64_t f : formats)
    offered += (offered.empty() ? "" : ", ") + std::to_string(f);
  throw XrUnavailable("the OpenXR runtime " + runtime +
                      " offers no sRGB RGBA8 swapchain format (VK_FORMAT_R8G8B8A8_SRGB or "
                      "VK_FORMAT_B8G8R8A8_SRGB); it offers VkFormat " +
                      (offered.empty() ? std::string("none") : offered) + kFallback);
}

void OpenXrSink::Impl::stop(std::string reason) {
  if (!stopped) stop_reason = std::move(reason);
  stopped = true;
}

void OpenXrSink::Impl::on_state(XrSessionState next) {
  state = next;
  switch (next) {
    case XR_SESSION_STATE_READY:
      if (!stopped && !running) {
        XrSessionBeginInfo begin{};
        begin.type = XR_TYPE_SESSION_BEGIN_INFO;
        begin.primaryViewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
        xr_frame(xrBeginSession(session, &begin), "xrBeginSession");
        running = true;
      }
      break;
    case XR_SESSION_STATE_STOPPING:
      if (running) {
        xr_frame(xrEndSession(session), "xrEndSession");
        running = false;
      }
      break;
    case XR_SESSION_STATE_EXITING:
      stop(
          "the OpenXR runtime ended the session (EXITING): the headset was taken off or the "
          "user quit");
      break;
    case XR_SESSION_STATE_LOSS_PENDING:
      running = false;  // the session is going away: no more frame calls
      stop(
          "the OpenXR runtime is losing the session (LOSS_PENDING): the headset was "
          "disconnected");
      break;
    default:
      break;
  }
}

void OpenXrSink::Impl::poll_events() {
  for (;;) {
    XrEventDataBuffer event{};
    event.type = XR_TYPE_EVENT_DATA_BUFFER;
    if (xrPollEvent(instance, &event) != XR_SUCCESS) return;
    if (event.type == XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED) {
      const auto& changed = reinterpret_cast<const XrEventDataSessionStateChanged&>(event);
      if (changed.session == session) on_state(changed.state);
    } else if (event.type == XR_TYPE_EVENT_DATA_INSTANCE_LOSS_PENDING) {
      running = false;
      stop("the OpenXR runtime is going away (instance loss pending)");
    }
  }
}

std::uint32_t OpenXrSink::Impl::memory_type(std::uint32_t bits, VkMemoryPropertyFlags flags) const {
  VkPhysicalDeviceMemoryProperties memory;
  vkGetPhysicalDeviceMemoryProperties(physical, &memory);
  for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i) {
    if ((bits & (1u << i)) != 0 && (memory.memoryTypes[i].propertyFlags & flags) == flags) return i;
  }
  throw RenderError("the OpenXR sink's Vulkan device has no host-visible, coherent memory");
}

void OpenXrSink::Impl::make_swapchains(std::uint32_t w, std::uint32_t h) {
  if (w > max_width || h > max_height) {
    throw RenderError("the frame's eye size " + std::to_string(w) + "x" + std::to_string(h) +
                      " exceeds the largest image the OpenXR runtime " + runtime + " takes (" +
                      std::to_string(max_width) + "x" + std::to_string(max_height) + ")");
  }
  for (Eye& eye : eyes) {
    XrSwapchainCreateInfo info{};
    info.type = XR_TYPE_SWAPCHAIN_CREATE_INFO;
    info.usageFlags = XR_SWAPCHAIN_USAGE_TRANSFER_DST_BIT | XR_SWAPCHAIN_USAGE_COLOR_ATTACHMENT_BIT;
    info.format = format;
    info.sampleCount = 1;
    info.width = w;
    info.height = h;
    info.faceCount = 1;
    info.arraySize = 1;
    info.mipCount = 1;
    xr_frame(xrCreateSwapchain(session, &info, &eye.swapchain), "xrCreateSwapchain");
    std::uint32_t count = 0;
    xr_frame(xrEnumerateSwapchainImages(eye.swapchain, 0, &count, nullptr),
             "xrEnumerateSwapchainImages");
    XrSwapchainImageVulkan2KHR blank{};
    blank.type = XR_TYPE_SWAPCHAIN_IMAGE_VULKAN2_KHR;
    std::vector<XrSwapchainImageVulkan2KHR> images(count, blank);
    xr_frame(
        xrEnumerateSwapchainImages(eye.swapchain, count, &count,
                                   reinterpret_cast<XrSwapchainImageBaseHeader*>(images.data())),
        "xrEnumerateSwapchainImages");
    for (const XrSwapchainImageVulkan2KHR& image : images)
      eye.images.push_back(image.image);
  }
  // One staging buffer for both eyes, kept for the sink's life: no allocation per frame.
  VkBufferCreateInfo buffer{};
  buffer.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  buffer.size = VkDeviceSize{w} * h * 4 * 2;
  buffer.usage = VK_BUFFER_USAGE_TRANSFER_SRC_BIT;
  vk::check(vkCreateBuffer(device, &buffer, nullptr, &staging), "vkCreateBuffer (staging)");
  VkMemoryRequirements needs;
  vkGetBufferMemoryRequirements(device, staging, &needs);
  VkMemoryAllocateInfo allocate{};
  allocate.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
  allocate.allocationSize = needs.size;
  allocate.memoryTypeIndex =
      memory_type(needs.memoryTypeBits,
                  VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  vk::check(vkAllocateMemory(device, &allocate, nullptr, &staging_memory),
            "vkAllocateMemory (staging)");
  vk::check(vkBindBufferMemory(device, staging, staging_memory, 0), "vkBindBufferMemory");
  void* mapped = nullptr;
  vk::check(vkMapMemory(device, staging_memory, 0, VK_WHOLE_SIZE, 0, &mapped), "vkMapMemory");
  staging_bytes = static_cast<std::uint8_t*>(mapped);
  width = w;
  height = h;
}

void OpenXrSink::Impl::upload(const StereoFrame& frame) {
  const std::size_t eye_bytes = std::size_t{width} * height * 4;
  for (int e = 0; e < 2; ++e) {
    const std::span<const std::uint8_t> src = frame.eye(e);
    std::uint8_t* dst = staging_bytes + static_cast<std::size_t>(e) * eye_bytes;
    if (!bgra) {
      std::memcpy(dst, src.data(), eye_bytes);
    } else {
      for (std::size_t i = 0; i < eye_bytes; i += 4) {
        dst[i] = src[i + 2];
        dst[i + 1] = src[i + 1];
        dst[i + 2] = src[i];
        dst[i + 3] = src[i + 3];
      }
    }
  }
  std::array<std::uint32_t, 2> index{};
  for (std::size_t e = 0; e < 2; ++e) {
    XrSwapchainImageAcquireInfo acquire{};
    acquire.type = XR_TYPE_SWAPCHAIN_IMAGE_ACQUIRE_INFO;
    xr_frame(xrAcquireSwapchainImage(eyes[e].swapchain, &acquire, &index[e]),
             "xrAcquireSwapchainImage");
    XrSwapchainImageWaitInfo wait{};
    wait.type = XR_TYPE_SWAPCHAIN_IMAGE_WAIT_INFO;
    wait.timeout = 100'000'000;  // 100 ms: far longer than any frame
    xr_frame(xrWaitSwapchainImage(eyes[e].swapchain, &wait), "xrWaitSwapchainImage");
  }
  VkCommandBufferBeginInfo begin{};
  begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  vk::check(vkResetCommandBuffer(commands, 0), "vkResetCommandBuffer");
  vk::check(vkBeginCommandBuffer(commands, &begin), "vkBeginCommandBuffer");
  for (std::size_t e = 0; e < 2; ++e) {
    const VkImage image = eyes[e].images[index[e]];
    // Swapchain images are handed over in COLOR_ATTACHMENT_OPTIMAL and must go back in it.
    image_barrier(commands, image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                  VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.bufferOffset = static_cast<VkDeviceSize>(e * eye_bytes);
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {width, height, 1};
    vkCmdCopyBufferToImage(commands, staging, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &region);
    image_barrier(commands, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                  VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                  VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                  VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT);
  }
  vk::check(vkEndCommandBuffer(commands), "vkEndCommandBuffer");
  VkSubmitInfo submit{};
  submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &commands;
  vk::check(vkQueueSubmit(queue, 1, &submit, fence), "vkQueueSubmit (OpenXR upload)");
  // Waiting here frees the staging buffer for the next frame and hands the runtime finished
  // images (a compositor may read them from another queue without waiting on ours).
  vk::check(vkWaitForFences(device, 1, &fence, VK_TRUE, UINT64_MAX), "vkWaitForFences");
  vk::check(vkResetFences(device, 1, &fence), "vkResetFences");
  for (const Eye& eye : eyes) {
    XrSwapchainImageReleaseInfo release_info{};
    release_info.type = XR_TYPE_SWAPCHAIN_IMAGE_RELEASE_INFO;
    xr_frame(xrReleaseSwapchainImage(eye.swapchain, &release_info), "xrReleaseSwapchainImage");
  }
}

void OpenXrSink::Impl::end_frame(XrTime display_time, const StereoFrame* frame) {
  std::array<XrCompositionLayerProjectionView, 2> views{};
  XrCompositionLayerProjection layer{};
  const XrCompositionLayerBaseHeader* layers[] = {
      reinterpret_cast<const XrCompositionLayerBaseHeader*>(&layer)};
  XrFrameEndInfo end{};
  end.type = XR_TYPE_FRAME_END_INFO;
  end.displayTime = display_time;
  end.environmentBlendMode = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
  if (frame != nullptr) {
    const std::array<EyeView, 2> eye = eye_views(options.rendered, frame->pose);
    for (std::size_t e = 0; e < 2; ++e) {
      XrCompositionLayerProjectionView& v = views[e];
      v.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW;
      v.pose = xr_pose(eye[e].position_mm, frame->pose.orientation);
      const EyeFov& fov = options.rendered.fov[e];
      v.fov = {fov.angle_left, fov.angle_right, fov.angle_up, fov.angle_down};
      v.subImage.swapchain = eyes[e].swapchain;
      v.subImage.imageRect = {
          {0, 0}, {static_cast<std::int32_t>(width), static_cast<std::int32_t>(height)}};
      v.subImage.imageArrayIndex = 0;
    }
    layer.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION;
    layer.space = space;
    layer.viewCount = 2;
    layer.views = views.data();
    end.layerCount = 1;
    end.layers = layers;
  }
  xr_frame(xrEndFrame(session, &end), "xrEndFrame");
}

void OpenXrSink::Impl::release() {
  if (session != XR_NULL_HANDLE) {
    // End the session the way the specification asks: request the exit, end it at STOPPING.
    const auto quiet_poll = [this] {
      try {
        poll_events();
      } catch (const RenderError&) {
        running = false;  // xrEndSession failed: the session is destroyed below all the same
      }
    };
    if (running && !stopped && XR_SUCCEEDED(xrRequestExitSession(session))) {
      for (int i = 0; i < 500 && running; ++i) {
        quiet_poll();
        if (running) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      quiet_poll();  // IDLE and EXITING follow xrEndSession
    }
    for (Eye& eye : eyes) {
      if (eye.swapchain != XR_NULL_HANDLE) xrDestroySwapchain(eye.swapchain);
      eye.swapchain = XR_NULL_HANDLE;
    }
    if (space != XR_NULL_HANDLE) xrDestroySpace(space);
    xrDestroySession(session);
    space = XR_NULL_HANDLE;
    session = XR_NULL_HANDLE;
  }
  if (device != VK_NULL_HANDLE) {
    vkDeviceWaitIdle(device);
    if (staging_bytes != nullptr) vkUnmapMemory(device, staging_memory);
    if (staging != VK_NULL_HANDLE) vkDestroyBuffer(device, staging, nullptr);
    if (staging_memory != VK_NULL_HANDLE) vkFreeMemory(device, staging_memory, nullptr);
    if (fence != VK_NULL_HANDLE) vkDestroyFence(device, fence, nullptr);
    if (pool != VK_NULL_HANDLE) vkDestroyCommandPool(device, pool, nullptr);
    vkDestroyDevice(device, nullptr);
    device = VK_NULL_HANDLE;
  }
  if (messenger != VK_NULL_HANDLE) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(vk_instance, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy != nullptr) destroy(vk_instance, messenger, nullptr);
    messenger = VK_NULL_HANDLE;
  }
  if (vk_instance != VK_NULL_HANDLE) vkDestroyInstance(vk_instance, nullptr);
  vk_instance = VK_NULL_HANDLE;
  if (instance != XR_NULL_HANDLE) xrDestroyInstance(instance);
  instance = XR_NULL_HANDLE;
}

OpenXrSink::OpenXrSink(const std::string& application_name)
    : OpenXrSink(OpenXrSinkOptions{application_name, {}, false, false}) {}

OpenXrSink::OpenXrSink(const OpenXrSinkOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->create_instance();
  impl_->describe_system();
  impl_->create_vulkan();
  impl_->create_session();
  impl_->choose_format();
  impl_->poll_events();  // a runtime that is ready at once begins the session here
}

OpenXrSink::~OpenXrSink() = default;

void OpenXrSink::consume(const StereoFrame& frame) {
  Impl& s = *impl_;
  ++s.stats.frames_consumed;
  s.poll_events();
  if (!s.running || s.stopped) {
    ++s.stats.frames_dropped;
    return;
  }
  if (s.width == 0) {
    s.make_swapchains(frame.eye_width, frame.eye_height);
  } else if (frame.eye_width != s.width || frame.eye_height != s.height) {
    throw RenderError(
        "a frame of " + std::to_string(frame.eye_width) + "x" + std::to_string(frame.eye_height) +
        " per eye reached the OpenXR sink, "
        "whose swapchains are " +
        std::to_string(s.width) + "x" + std::to_string(s.height) + " (made at the first frame)");
  }
  XrFrameWaitInfo wait{};
  wait.type = XR_TYPE_FRAME_WAIT_INFO;
  XrFrameState frame_state{};
  frame_state.type = XR_TYPE_FRAME_STATE;
  const auto waiting = std::chrono::steady_clock::now();
  s.xr_frame(xrWaitFrame(s.session, &wait, &frame_state), "xrWaitFrame");
  s.stats.wait_frame_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - waiting).count();
  XrFrameBeginInfo begin{};
  begin.type = XR_TYPE_FRAME_BEGIN_INFO;
  s.xr_frame(xrBeginFrame(s.session, &begin), "xrBeginFrame");
  if (frame_state.shouldRender != XR_TRUE) {
    s.end_frame(frame_state.predictedDisplayTime, nullptr);
    ++s.stats.frames_not_rendered;
    return;
  }
  const auto uploading = std::chrono::steady_clock::now();
  s.upload(frame);
  s.stats.upload_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - uploading)
          .count();
  s.end_frame(frame_state.predictedDisplayTime, &frame);
  ++s.stats.frames_submitted;
}

const HeadsetDescription& OpenXrSink::headset() const {
  return impl_->headset;
}
const std::string& OpenXrSink::runtime_name() const {
  return impl_->runtime;
}
OpenXrSinkStats OpenXrSink::stats() const {
  return impl_->stats;
}
std::string OpenXrSink::session_state() const {
  return state_name(impl_->state);
}
bool OpenXrSink::presenting() const {
  return impl_->running && !impl_->stopped;
}
const std::string& OpenXrSink::stop_reason() const {
  return impl_->stop_reason;
}
std::string OpenXrSink::swapchain_format() const {
  return impl_->bgra ? "VK_FORMAT_B8G8R8A8_SRGB" : "VK_FORMAT_R8G8B8A8_SRGB";
}
std::size_t OpenXrSink::validation_messages() const {
  return impl_->validation.messages.load();
}
std::vector<std::string> OpenXrSink::validation_log() const {
  const std::lock_guard<std::mutex> lock(impl_->validation.mutex);
  return impl_->validation.lines;
}

}  // namespace bisturi::render
