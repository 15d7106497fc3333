// Instance, system and view configuration of the simulated headset, its configuration from the
// environment, and XR_KHR_vulkan_enable2 (the application's Vulkan instance and device are made
// here, as a real runtime would make them, so it can add what its compositor needs).

#include <cstdlib>
#include <cstring>
#include <sstream>

#include "api.h"

namespace bisturi::xrsim {

namespace {

constexpr const char* kRuntimeName = "bisturi simulated headset";
constexpr XrSystemId kSystem = 1;

template <typename T>
XrResult two_call(std::uint32_t capacity, std::uint32_t* count, T* out,
                  const std::vector<T>& values) {
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *count = static_cast<std::uint32_t>(values.size());
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < values.size()) return XR_ERROR_SIZE_INSUFFICIENT;
  if (out == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  for (std::size_t i = 0; i < values.size(); ++i)
    out[i] = values[i];
  return XR_SUCCESS;
}

std::string env(const char* name) {
  const char* value = std::getenv(name);
  return value != nullptr ? value : "";
}

VkFormat parse_format(const std::string& name) {
  if (name == "rgba_srgb") return VK_FORMAT_R8G8B8A8_SRGB;
  if (name == "bgra_srgb") return VK_FORMAT_B8G8R8A8_SRGB;
  if (name == "rgba_unorm") return VK_FORMAT_R8G8B8A8_UNORM;
  if (name == "rgba16f") return VK_FORMAT_R16G16B16A16_SFLOAT;
  return VK_FORMAT_UNDEFINED;
}

Instance* checked(XrInstance handle) {
  return object<Instance>(handle);
}

}  // namespace

Config Config::from_environment() {
  Config c;
  if (const std::string hz = env("BISTURI_XR_SIM_HZ"); !hz.empty()) {
    const double v = std::atof(hz.c_str());
    if (v > 0.0) c.display_hz = v;
  }
  if (const std::string size = env("BISTURI_XR_SIM_EYE_SIZE"); !size.empty()) {
    unsigned w = 0, h = 0;
    if (std::sscanf(size.c_str(), "%ux%u", &w, &h) == 2 && w > 0 && h > 0) {
      c.eye_width = w;
      c.eye_height = h;
    }
  }
  c.still_head = env("BISTURI_XR_SIM_STILL") == "1";
  {
    std::stringstream list(env("BISTURI_XR_SIM_INVALID_VIEWS"));
    for (std::string item; std::getline(list, item, ',');) {
      if (!item.empty()) c.invalid_view_frames.push_back(std::strtoull(item.c_str(), nullptr, 10));
    }
  }
  if (const std::string n = env("BISTURI_XR_SIM_LOSE_AFTER"); !n.empty()) {
    c.lose_after_frames = std::atoll(n.c_str());
  }
  if (const std::string ms = env("BISTURI_XR_SIM_LOST_MS"); !ms.empty()) {
    c.lost_ms = std::atof(ms.c_str());
  }
  if (const std::string n = env("BISTURI_XR_SIM_LOSE_INSTANCE_AFTER"); !n.empty()) {
    c.lose_instance_after_frames = std::atoll(n.c_str());
  }
  if (const std::string range = env("BISTURI_XR_SIM_TRIGGER_FRAMES"); !range.empty()) {
    long long a = -1, b = -1;
    if (std::sscanf(range.c_str(), "%lld-%lld", &a, &b) == 2 && a >= 0 && b >= a) {
      c.trigger_from = a;
      c.trigger_to = b;
    }
  }
  c.log_path = env("BISTURI_XR_SIM_LOG");
  c.png_dir = env("BISTURI_XR_SIM_PNG_DIR");
  if (const std::string n = env("BISTURI_XR_SIM_EXIT_AFTER"); !n.empty()) {
    c.exit_after_frames = std::atoll(n.c_str());
  }
  // Real runtimes tend to list a BGRA format first; offering both exercises the choice.
  std::string formats = env("BISTURI_XR_SIM_FORMATS");
  if (formats.empty()) formats = "bgra_srgb,rgba_srgb,rgba_unorm";
  std::stringstream list(formats);
  for (std::string item; std::getline(list, item, ',');) {
    if (const VkFormat f = parse_format(item); f != VK_FORMAT_UNDEFINED) c.formats.push_back(f);
  }
  return c;
}

const char* format_name(VkFormat format) {
  switch (format) {
    case VK_FORMAT_R8G8B8A8_SRGB:
      return "R8G8B8A8_SRGB";
    case VK_FORMAT_B8G8R8A8_SRGB:
      return "B8G8R8A8_SRGB";
    case VK_FORMAT_R8G8B8A8_UNORM:
      return "R8G8B8A8_UNORM";
    case VK_FORMAT_R16G16B16A16_SFLOAT:
      return "R16G16B16A16_SFLOAT";
    default:
      return "?";
  }
}

XrResult EnumerateInstanceExtensionProperties(const char* layer, std::uint32_t capacity,
                                              std::uint32_t* count, XrExtensionProperties* out) {
  if (layer != nullptr) return XR_ERROR_API_LAYER_NOT_PRESENT;
  XrExtensionProperties vulkan{};
  vulkan.type = XR_TYPE_EXTENSION_PROPERTIES;
  std::strncpy(vulkan.extensionName, XR_KHR_VULKAN_ENABLE2_EXTENSION_NAME,
               XR_MAX_EXTENSION_NAME_SIZE - 1);
  vulkan.extensionVersion = XR_KHR_vulkan_enable2_SPEC_VERSION;
  XrExtensionProperties timespec{};
  timespec.type = XR_TYPE_EXTENSION_PROPERTIES;
  std::strncpy(timespec.extensionName, XR_KHR_CONVERT_TIMESPEC_TIME_EXTENSION_NAME,
               XR_MAX_EXTENSION_NAME_SIZE - 1);
  timespec.extensionVersion = XR_KHR_convert_timespec_time_SPEC_VERSION;
  if (capacity >= 2 && out != nullptr) {
    vulkan.next = out[0].next;
    timespec.next = out[1].next;
  }
  return two_call<XrExtensionProperties>(capacity, count, out, {vulkan, timespec});
}

XrResult CreateInstance(const XrInstanceCreateInfo* info, XrInstance* instance) {
  if (info == nullptr || instance == nullptr || info->type != XR_TYPE_INSTANCE_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (XR_VERSION_MAJOR(info->applicationInfo.apiVersion) != 1) {
    return XR_ERROR_API_VERSION_UNSUPPORTED;
  }
  if (info->enabledApiLayerCount > 0) return XR_ERROR_API_LAYER_NOT_PRESENT;
  bool vulkan2 = false, timespec = false;
  for (std::uint32_t i = 0; i < info->enabledExtensionCount; ++i) {
    const char* name = info->enabledExtensionNames[i];
    if (std::strcmp(name, XR_KHR_VULKAN_ENABLE2_EXTENSION_NAME) == 0) {
      vulkan2 = true;
    } else if (std::strcmp(name, XR_KHR_CONVERT_TIMESPEC_TIME_EXTENSION_NAME) == 0) {
      timespec = true;
    } else {
      return XR_ERROR_EXTENSION_NOT_PRESENT;
    }
  }
  auto* created = new Instance();
  created->config = Config::from_environment();
  created->application = info->applicationInfo.applicationName;
  created->vulkan2 = vulkan2;
  created->convert_timespec = timespec;
  created->start_ns = now_ns();
  created->log.open(created->config.log_path);
  std::string formats = "[";
  for (const VkFormat f : created->config.formats) {
    if (formats.size() > 1) formats += ",";
    formats += json_string(format_name(f));
  }
  created->log.write("instance",
                     "\"application\":" + json_string(created->application) + ",\"display_hz\":" +
                         std::to_string(created->config.display_hz) + ",\"formats\":" + formats +
                         "],\"convert_timespec\":" + (timespec ? "true" : "false"));
  track(created);
  *instance = handle<XrInstance>(created);
  return XR_SUCCESS;
}

XrResult DestroyInstance(XrInstance handle_) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance->session != nullptr) DestroySession(handle<XrSession>(instance->session));
  destroy_action_sets(*instance);
  instance->log.write("instance_destroyed");
  untrack(instance);
  delete instance;
  return XR_SUCCESS;
}

XrResult GetInstanceProperties(XrInstance handle_, XrInstanceProperties* properties) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (properties == nullptr || properties->type != XR_TYPE_INSTANCE_PROPERTIES) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  properties->runtimeVersion = XR_MAKE_VERSION(0, 1, 0);
  std::strncpy(properties->runtimeName, kRuntimeName, XR_MAX_RUNTIME_NAME_SIZE - 1);
  return XR_SUCCESS;
}

XrResult ResultToString(XrInstance handle_, XrResult value,
                        char buffer[XR_MAX_RESULT_STRING_SIZE]) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  const char* name = nullptr;
  switch (value) {
#define BISTURI_XRSIM_RESULT(n, v) \
  case n:                          \
    name = #n;                     \
    break;
    XR_LIST_ENUM_XrResult(BISTURI_XRSIM_RESULT)
#undef BISTURI_XRSIM_RESULT
        default : break;
  }
  if (name != nullptr) {
    std::snprintf(buffer, XR_MAX_RESULT_STRING_SIZE, "%s", name);
  } else {
    std::snprintf(buffer, XR_MAX_RESULT_STRING_SIZE, "XR_UNKNOWN_%s_%d",
                  XR_SUCCEEDED(value) ? "SUCCESS" : "FAILURE", static_cast<int>(value));
  }
  return XR_SUCCESS;
}

XrResult StructureTypeToString(XrInstance handle_, XrStructureType value,
                               char buffer[XR_MAX_STRUCTURE_NAME_SIZE]) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  const char* name = nullptr;
  switch (value) {
#define BISTURI_XRSIM_TYPE(n, v) \
  case n:                        \
    name = #n;                   \
    break;
    XR_LIST_ENUM_XrStructureType(BISTURI_XRSIM_TYPE)
#undef BISTURI_XRSIM_TYPE
        default : break;
  }
  std::snprintf(buffer, XR_MAX_STRUCTURE_NAME_SIZE, "%s",
                name != nullptr ? name : "XR_UNKNOWN_STRUCTURE_TYPE");
  return XR_SUCCESS;
}

XrResult GetSystem(XrInstance handle_, const XrSystemGetInfo* info, XrSystemId* system) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (info == nullptr || system == nullptr || info->type != XR_TYPE_SYSTEM_GET_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (info->formFactor != XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY) {
    return XR_ERROR_FORM_FACTOR_UNSUPPORTED;
  }
  // After a session loss the headset is away (unplugged) for a while.
  if (now_ns() < instance->headset_back_ns) return XR_ERROR_FORM_FACTOR_UNAVAILABLE;
  *system = kSystem;
  return XR_SUCCESS;
}

XrResult GetSystemProperties(XrInstance handle_, XrSystemId system,
                             XrSystemProperties* properties) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (system != kSystem) return XR_ERROR_SYSTEM_INVALID;
  if (properties == nullptr || properties->type != XR_TYPE_SYSTEM_PROPERTIES) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  properties->systemId = kSystem;
  properties->vendorId = 0;
  std::strncpy(properties->systemName, kRuntimeName, XR_MAX_SYSTEM_NAME_SIZE - 1);
  properties->graphicsProperties.maxSwapchainImageWidth = instance->config.max_eye_size;
  properties->graphicsProperties.maxSwapchainImageHeight = instance->config.max_eye_size;
  properties->graphicsProperties.maxLayerCount = 1;
  properties->trackingProperties.orientationTracking = XR_TRUE;
  properties->trackingProperties.positionTracking = XR_TRUE;
  return XR_SUCCESS;
}

XrResult EnumerateViewConfigurations(XrInstance handle_, XrSystemId system, std::uint32_t capacity,
                                     std::uint32_t* count, XrViewConfigurationType* out) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (system != kSystem) return XR_ERROR_SYSTEM_INVALID;
  return two_call<XrViewConfigurationType>(capacity, count, out,
                                           {XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO});
}

XrResult EnumerateViewConfigurationViews(XrInstance handle_, XrSystemId system,
                                         XrViewConfigurationType type, std::uint32_t capacity,
                                         std::uint32_t* count, XrViewConfigurationView* out) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (system != kSystem) return XR_ERROR_SYSTEM_INVALID;
  if (type != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO) {
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  }
  XrViewConfigurationView view{};
  view.type = XR_TYPE_VIEW_CONFIGURATION_VIEW;
  view.recommendedImageRectWidth = instance->config.eye_width;
  view.recommendedImageRectHeight = instance->config.eye_height;
  view.maxImageRectWidth = instance->config.max_eye_size;
  view.maxImageRectHeight = instance->config.max_eye_size;
  view.recommendedSwapchainSampleCount = 1;
  view.maxSwapchainSampleCount = 1;
  return two_call<XrViewConfigurationView>(capacity, count, out, {view, view});
}

XrResult EnumerateEnvironmentBlendModes(XrInstance handle_, XrSystemId system,
                                        XrViewConfigurationType type, std::uint32_t capacity,
                                        std::uint32_t* count, XrEnvironmentBlendMode* out) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (system != kSystem) return XR_ERROR_SYSTEM_INVALID;
  if (type != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO) {
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  }
  return two_call<XrEnvironmentBlendMode>(capacity, count, out, {XR_ENVIRONMENT_BLEND_MODE_OPAQUE});
}

// --- XR_KHR_vulkan_enable2 ---

XrResult GetVulkanGraphicsRequirements2KHR(XrInstance handle_, XrSystemId system,
                                           XrGraphicsRequirementsVulkanKHR* requirements) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (system != kSystem) return XR_ERROR_SYSTEM_INVALID;
  if (requirements == nullptr || requirements->type != XR_TYPE_GRAPHICS_REQUIREMENTS_VULKAN2_KHR) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  requirements->minApiVersionSupported = XR_MAKE_VERSION(1, 1, 0);
  requirements->maxApiVersionSupported = XR_MAKE_VERSION(1, 3, 0);
  instance->requirements_queried = true;
  return XR_SUCCESS;
}

XrResult CreateVulkanInstanceKHR(XrInstance handle_, const XrVulkanInstanceCreateInfoKHR* info,
                                 VkInstance* vk_instance, VkResult* vk_result) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || vk_instance == nullptr || vk_result == nullptr ||
      info->type != XR_TYPE_VULKAN_INSTANCE_CREATE_INFO_KHR || info->systemId != kSystem ||
      info->pfnGetInstanceProcAddr == nullptr || info->vulkanCreateInfo == nullptr) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (!instance->requirements_queried) return XR_ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING;
  auto create = reinterpret_cast<PFN_vkCreateInstance>(
      info->pfnGetInstanceProcAddr(VK_NULL_HANDLE, "vkCreateInstance"));
  if (create == nullptr) return XR_ERROR_RUNTIME_FAILURE;
  *vk_result = create(info->vulkanCreateInfo, info->vulkanAllocator, vk_instance);
  if (*vk_result != VK_SUCCESS) return XR_ERROR_RUNTIME_FAILURE;
  instance->vk_instance = *vk_instance;
  return XR_SUCCESS;
}

XrResult GetVulkanGraphicsDevice2KHR(XrInstance handle_,
                                     const XrVulkanGraphicsDeviceGetInfoKHR* info,
                                     VkPhysicalDevice* device) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || device == nullptr ||
      info->type != XR_TYPE_VULKAN_GRAPHICS_DEVICE_GET_INFO_KHR || info->systemId != kSystem ||
      info->vulkanInstance == VK_NULL_HANDLE) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  // The headset's "GPU": the first device with a graphics queue (lavapipe without a GPU).
  std::uint32_t count = 0;
  if (vkEnumeratePhysicalDevices(info->vulkanInstance, &count, nullptr) != VK_SUCCESS) {
    return XR_ERROR_RUNTIME_FAILURE;
  }
  std::vector<VkPhysicalDevice> devices(count);
  vkEnumeratePhysicalDevices(info->vulkanInstance, &count, devices.data());
  for (VkPhysicalDevice d : devices) {
    std::uint32_t families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(d, &families, nullptr);
    std::vector<VkQueueFamilyProperties> family(families);
    vkGetPhysicalDeviceQueueFamilyProperties(d, &families, family.data());
    for (const VkQueueFamilyProperties& f : family) {
      if ((f.queueFlags & VK_QUEUE_GRAPHICS_BIT) != 0) {
        instance->physical = d;
        *device = d;
        return XR_SUCCESS;
      }
    }
  }
  return XR_ERROR_RUNTIME_FAILURE;
}

XrResult CreateVulkanDeviceKHR(XrInstance handle_, const XrVulkanDeviceCreateInfoKHR* info,
                               VkDevice* vk_device, VkResult* vk_result) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || vk_device == nullptr || vk_result == nullptr ||
      info->type != XR_TYPE_VULKAN_DEVICE_CREATE_INFO_KHR || info->systemId != kSystem ||
      info->pfnGetInstanceProcAddr == nullptr || info->vulkanCreateInfo == nullptr) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (instance->physical == VK_NULL_HANDLE || info->vulkanPhysicalDevice != instance->physical) {
    return XR_ERROR_VALIDATION_FAILURE;  // must be the device xrGetVulkanGraphicsDevice2KHR named
  }
  auto create = reinterpret_cast<PFN_vkCreateDevice>(
      info->pfnGetInstanceProcAddr(instance->vk_instance, "vkCreateDevice"));
  if (create == nullptr) return XR_ERROR_RUNTIME_FAILURE;
  *vk_result =
      create(info->vulkanPhysicalDevice, info->vulkanCreateInfo, info->vulkanAllocator, vk_device);
  if (*vk_result != VK_SUCCESS) return XR_ERROR_RUNTIME_FAILURE;
  instance->devices.push_back(*vk_device);
  return XR_SUCCESS;
}

// --- XR_KHR_convert_timespec_time: XrTime is CLOCK_MONOTONIC in nanoseconds ---

XrResult ConvertTimespecTimeToTimeKHR(XrInstance handle_, const struct timespec* timespec_time,
                                      XrTime* time) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (timespec_time == nullptr || time == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *time = static_cast<XrTime>(timespec_time->tv_sec) * 1'000'000'000 + timespec_time->tv_nsec;
  return XR_SUCCESS;
}

XrResult ConvertTimeToTimespecTimeKHR(XrInstance handle_, XrTime time,
                                      struct timespec* timespec_time) {
  Instance* instance = checked(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (timespec_time == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  if (time <= 0) return XR_ERROR_TIME_INVALID;
  timespec_time->tv_sec = static_cast<time_t>(time / 1'000'000'000);
  timespec_time->tv_nsec = static_cast<long>(time % 1'000'000'000);
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
