#pragma once
// The Vulkan instance, device and queue the renderer draws with, and the validation-layer
// messages they produced (counted for the tests, never printed).

#include <vulkan/vulkan.h>

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
#include <string>
#include <vector>

#include "bisturi/runtime/render/stereo_renderer.h"

namespace bisturi::render::vk {

/// Throws RenderError naming the call and the result when `result` is not VK_SUCCESS.
void check(VkResult result, const char* what);
const char* result_name(VkResult result);

/// How an OpenXR runtime makes the instance and the device instead (XR_KHR_vulkan_enable2): it
/// adds the extensions its compositor needs and names the physical device it shows frames from,
/// so the renderer draws on the device the runtime reads. Each throws on failure.
struct RuntimeCreation {
  std::function<VkInstance(const VkInstanceCreateInfo&)> create_instance;
  std::function<VkPhysicalDevice(VkInstance)> physical_device;
  std::function<VkDevice(VkPhysicalDevice, const VkDeviceCreateInfo&)> create_device;
};

class Context {
 public:
  Context(bool validation, DevicePreference preference);
  /// The instance and device made through the runtime (which picks the physical device).
  Context(bool validation, const RuntimeCreation& runtime);
  ~Context();
  Context(const Context&) = delete;
  Context& operator=(const Context&) = delete;

  [[nodiscard]] VkInstance instance() const { return instance_; }
  [[nodiscard]] VkDevice device() const { return device_; }
  [[nodiscard]] VkPhysicalDevice physical_device() const { return physical_; }
  [[nodiscard]] VkQueue queue() const { return queue_; }
  [[nodiscard]] std::uint32_t queue_family() const { return queue_family_; }
  [[nodiscard]] const VkPhysicalDeviceProperties& properties() const { return properties_; }
  [[nodiscard]] bool is_cpu() const {
    return properties_.deviceType == VK_PHYSICAL_DEVICE_TYPE_CPU;
  }
  /// A memory type allowed by `type_bits` with all of `required` (and, when there is one, all of
  /// `preferred` too); throws RenderError if none.
  [[nodiscard]] std::uint32_t memory_type(std::uint32_t type_bits, VkMemoryPropertyFlags required,
                                          VkMemoryPropertyFlags preferred = 0) const;
  [[nodiscard]] VkMemoryPropertyFlags memory_flags(std::uint32_t type) const {
    return memory_.memoryTypes[type].propertyFlags;
  }

  [[nodiscard]] std::size_t validation_messages() const { return messages_.load(); }
  [[nodiscard]] std::vector<std::string> validation_log() const;
  /// Called by the debug messenger.
  void record_message(std::string text);

 private:
  void create_instance(bool validation, const RuntimeCreation* runtime);
  void pick_device(DevicePreference preference, VkPhysicalDevice only);
  void create_device(const RuntimeCreation* runtime);
  void release();

  VkInstance instance_ = VK_NULL_HANDLE;
  VkDebugUtilsMessengerEXT messenger_ = VK_NULL_HANDLE;
  VkPhysicalDevice physical_ = VK_NULL_HANDLE;
  VkDevice device_ = VK_NULL_HANDLE;
  VkQueue queue_ = VK_NULL_HANDLE;
  std::uint32_t queue_family_ = 0;
  VkPhysicalDeviceProperties properties_{};
  VkPhysicalDeviceMemoryProperties memory_{};
  std::atomic<std::size_t> messages_{0};
  mutable std::mutex log_mutex_;
  std::vector<std::string> log_;
};

}  // namespace bisturi::render::vk
