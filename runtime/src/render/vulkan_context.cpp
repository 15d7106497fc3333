#include "vulkan_context.h"

#include "vulkan_validation.h"

#include <algorithm>
#include <cstring>

#include "bisturi/runtime/render/errors.h"

namespace bisturi::render::vk {

namespace {

VKAPI_ATTR VkBool32 VKAPI_CALL on_message(VkDebugUtilsMessageSeverityFlagBitsEXT severity,
                                          VkDebugUtilsMessageTypeFlagsEXT /*types*/,
                                          const VkDebugUtilsMessengerCallbackDataEXT* data,
                                          void* user) {
  const char* level =
      (severity & VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT) != 0 ? "error" : "warning";
  std::string text = level;
  text += ": ";
  text += data != nullptr && data->pMessage != nullptr ? data->pMessage : "(no message)";
  static_cast<Context*>(user)->record_message(std::move(text));
  return VK_FALSE;
}

int device_rank(VkPhysicalDeviceType type, DevicePreference preference) {
  const bool cpu = type == VK_PHYSICAL_DEVICE_TYPE_CPU;
  if (preference == DevicePreference::Cpu) return cpu ? 0 : 1;
  if (preference == DevicePreference::Gpu && cpu) return 100;
  switch (type) {
    case VK_PHYSICAL_DEVICE_TYPE_DISCRETE_GPU:
      return 0;
    case VK_PHYSICAL_DEVICE_TYPE_INTEGRATED_GPU:
      return 1;
    case VK_PHYSICAL_DEVICE_TYPE_VIRTUAL_GPU:
      return 2;
    case VK_PHYSICAL_DEVICE_TYPE_CPU:
      return 3;
    default:
      return 4;
  }
}

}  // namespace

const char* result_name(VkResult result) {
  switch (result) {
    case VK_SUCCESS:
      return "VK_SUCCESS";
    case VK_NOT_READY:
      return "VK_NOT_READY";
    case VK_TIMEOUT:
      return "VK_TIMEOUT";
    case VK_ERROR_OUT_OF_HOST_MEMORY:
      return "VK_ERROR_OUT_OF_HOST_MEMORY";
    case VK_ERROR_OUT_OF_DEVICE_MEMORY:
      return "VK_ERROR_OUT_OF_DEVICE_MEMORY";
    case VK_ERROR_INITIALIZATION_FAILED:
      return "VK_ERROR_INITIALIZATION_FAILED";
    case VK_ERROR_DEVICE_LOST:
      return "VK_ERROR_DEVICE_LOST";
    case VK_ERROR_LAYER_NOT_PRESENT:
      return "VK_ERROR_LAYER_NOT_PRESENT";
    case VK_ERROR_EXTENSION_NOT_PRESENT:
      return "VK_ERROR_EXTENSION_NOT_PRESENT";
    case VK_ERROR_FEATURE_NOT_PRESENT:
      return "VK_ERROR_FEATURE_NOT_PRESENT";
    case VK_ERROR_INCOMPATIBLE_DRIVER:
      return "VK_ERROR_INCOMPATIBLE_DRIVER";
    case VK_ERROR_FORMAT_NOT_SUPPORTED:
      return "VK_ERROR_FORMAT_NOT_SUPPORTED";
    default:
      return "a Vulkan error";
  }
}

void check(VkResult result, const char* what) {
  if (result != VK_SUCCESS) {
    throw RenderError(std::string(what) + " failed: " + result_name(result) + " (" +
                      std::to_string(static_cast<int>(result)) + ")");
  }
}

Context::Context(bool validation, DevicePreference preference) {
  try {
    create_instance(validation, nullptr);
    pick_device(preference, VK_NULL_HANDLE);
    create_device(nullptr);
  } catch (...) {
    release();
    throw;
  }
}

Context::Context(bool validation, const RuntimeCreation& runtime) {
  try {
    create_instance(validation, &runtime);
    pick_device(DevicePreference::Any, runtime.physical_device(instance_));
    create_device(&runtime);
  } catch (...) {
    release();
    throw;
  }
}

Context::~Context() {
  release();
}

void Context::release() {
  if (device_ != VK_NULL_HANDLE) {
    vkDestroyDevice(device_, nullptr);
    device_ = VK_NULL_HANDLE;
  }
  if (messenger_ != VK_NULL_HANDLE) {
    auto destroy = reinterpret_cast<PFN_vkDestroyDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkDestroyDebugUtilsMessengerEXT"));
    if (destroy != nullptr) destroy(instance_, messenger_, nullptr);
    messenger_ = VK_NULL_HANDLE;
  }
  if (instance_ != VK_NULL_HANDLE) {
    vkDestroyInstance(instance_, nullptr);
    instance_ = VK_NULL_HANDLE;
  }
}

void Context::record_message(std::string text) {
  ++messages_;
  const std::lock_guard<std::mutex> lock(log_mutex_);
  if (log_.size() < 100) log_.push_back(std::move(text));
}

std::vector<std::string> Context::validation_log() const {
  const std::lock_guard<std::mutex> lock(log_mutex_);
  return log_;
}

void Context::create_instance(bool validation, const RuntimeCreation* runtime) {
  VkApplicationInfo app{};
  app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
  app.pApplicationName = "bisturi";
  app.pEngineName = "bisturi";
  app.apiVersion = VK_API_VERSION_1_2;

  std::vector<const char*> layers;
  std::vector<const char*> extensions;
  VkDebugUtilsMessengerCreateInfoEXT messenger = validation_messenger(on_message, this);
  if (validation) add_validation(layers, extensions);

  VkInstanceCreateInfo info{};
  info.sType = VK_STRUCTURE_TYPE_INSTANCE_CREATE_INFO;
  info.pApplicationInfo = &app;
  info.enabledLayerCount = static_cast<std::uint32_t>(layers.size());
  info.ppEnabledLayerNames = layers.data();
  info.enabledExtensionCount = static_cast<std::uint32_t>(extensions.size());
  info.ppEnabledExtensionNames = extensions.data();
  if (validation) info.pNext = &messenger;  // also reports on instance creation itself
  if (runtime != nullptr) {
    instance_ = runtime->create_instance(info);
  } else {
    const VkResult result = vkCreateInstance(&info, nullptr, &instance_);
    if (result == VK_ERROR_INCOMPATIBLE_DRIVER || result == VK_ERROR_INITIALIZATION_FAILED) {
      throw NoVulkanDevice(std::string("no Vulkan driver could be loaded (vkCreateInstance: ") +
                           result_name(result) +
                           "); install a driver, e.g. Mesa's lavapipe (mesa-vulkan-drivers)");
    }
    check(result, "vkCreateInstance");
  }
  if (validation) {
    auto create = reinterpret_cast<PFN_vkCreateDebugUtilsMessengerEXT>(
        vkGetInstanceProcAddr(instance_, "vkCreateDebugUtilsMessengerEXT"));
    if (create == nullptr) throw RenderError("vkCreateDebugUtilsMessengerEXT is not available");
    check(create(instance_, &messenger, nullptr, &messenger_), "vkCreateDebugUtilsMessengerEXT");
  }
}

void Context::pick_device(DevicePreference preference, VkPhysicalDevice only) {
  std::uint32_t count = 0;
  check(vkEnumeratePhysicalDevices(instance_, &count, nullptr), "vkEnumeratePhysicalDevices");
  std::vector<VkPhysicalDevice> devices(count);
  check(vkEnumeratePhysicalDevices(instance_, &count, devices.data()),
        "vkEnumeratePhysicalDevices");
  int best_rank = 1000;
  std::string refused;
  for (VkPhysicalDevice d : devices) {
    if (only != VK_NULL_HANDLE && d != only) continue;  // the runtime's device or none
    VkPhysicalDeviceProperties props;
    vkGetPhysicalDeviceProperties(d, &props);
    VkPhysicalDeviceVulkan11Features v11{};
    v11.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES;
    VkPhysicalDeviceFeatures2 features{};
    features.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_FEATURES_2;
    features.pNext = &v11;
    if (props.apiVersion < VK_API_VERSION_1_2) {
      refused += std::string(" ") + props.deviceName + " (Vulkan < 1.2);";
      continue;
    }
    vkGetPhysicalDeviceFeatures2(d, &features);
    if (v11.multiview != VK_TRUE) {
      refused += std::string(" ") + props.deviceName + " (no multiview);";
      continue;
    }
    std::uint32_t families = 0;
    vkGetPhysicalDeviceQueueFamilyProperties(d, &families, nullptr);
    std::vector<VkQueueFamilyProperties> family(families);
    vkGetPhysicalDeviceQueueFamilyProperties(d, &families, family.data());
    std::uint32_t graphics = families;
    for (std::uint32_t f = 0; f < families; ++f) {
      if ((family[f].queueFlags & VK_QUEUE_GRAPHICS_BIT) != 0) {
        graphics = f;
        break;
      }
    }
    if (graphics == families) continue;
    const int rank = device_rank(props.deviceType, preference);
    if (rank >= 100) continue;
    if (rank < best_rank) {
      best_rank = rank;
      physical_ = d;
      queue_family_ = graphics;
      properties_ = props;
    }
  }
  if (physical_ == VK_NULL_HANDLE) {
    throw NoVulkanDevice(
        "no Vulkan device with Vulkan 1.2, multiview and graphics" +
        (count == 0 ? std::string(" (the driver lists no device)") : ":" + refused));
  }
  vkGetPhysicalDeviceMemoryProperties(physical_, &memory_);
}

void Context::create_device(const RuntimeCreation* runtime) {
  const float priority = 1.0f;
  VkDeviceQueueCreateInfo queue{};
  queue.sType = VK_STRUCTURE_TYPE_DEVICE_QUEUE_CREATE_INFO;
  queue.queueFamilyIndex = queue_family_;
  queue.queueCount = 1;
  queue.pQueuePriorities = &priority;
  VkPhysicalDeviceVulkan11Features v11{};
  v11.sType = VK_STRUCTURE_TYPE_PHYSICAL_DEVICE_VULKAN_1_1_FEATURES;
  v11.multiview = VK_TRUE;
  VkDeviceCreateInfo info{};
  info.sType = VK_STRUCTURE_TYPE_DEVICE_CREATE_INFO;
  info.pNext = &v11;
  info.queueCreateInfoCount = 1;
  info.pQueueCreateInfos = &queue;
  if (runtime != nullptr) {
    device_ = runtime->create_device(physical_, info);
  } else {
    check(vkCreateDevice(physical_, &info, nullptr, &device_), "vkCreateDevice");
  }
  vkGetDeviceQueue(device_, queue_family_, 0, &queue_);
}

std::uint32_t Context::memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags required,
                                   VkMemoryPropertyFlags preferred) const {
  for (int pass = 0; pass < 2; ++pass) {
    const VkMemoryPropertyFlags wanted = pass == 0 ? (required | preferred) : required;
    for (std::uint32_t i = 0; i < memory_.memoryTypeCount; ++i) {
      if ((type_bits & (1u << i)) != 0 &&
          (memory_.memoryTypes[i].propertyFlags & wanted) == wanted) {
        return i;
      }
    }
  }
  throw RenderError("no Vulkan memory type with the properties needed");
}

}  // namespace bisturi::render::vk
