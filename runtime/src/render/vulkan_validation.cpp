#include "vulkan_validation.h"

#include <algorithm>
#include <cstdint>
#include <cstring>

#include "bisturi/runtime/render/errors.h"

namespace bisturi::render {

bool has_layer(const char* name) {
  std::uint32_t count = 0;
  if (vkEnumerateInstanceLayerProperties(&count, nullptr) != VK_SUCCESS) return false;
  std::vector<VkLayerProperties> layers(count);
  vkEnumerateInstanceLayerProperties(&count, layers.data());
  return std::any_of(layers.begin(), layers.end(), [&](const VkLayerProperties& l) {
    return std::strcmp(l.layerName, name) == 0;
  });
}

void add_validation(std::vector<const char*>& layers, std::vector<const char*>& extensions) {
  constexpr const char* kLayer = "VK_LAYER_KHRONOS_validation";
  if (!has_layer(kLayer)) {
    throw RenderError(
        "Vulkan validation was asked for but VK_LAYER_KHRONOS_validation is not installed "
        "(Debian: vulkan-validationlayers)");
  }
  layers.push_back(kLayer);
  extensions.push_back(VK_EXT_DEBUG_UTILS_EXTENSION_NAME);
}

VkDebugUtilsMessengerCreateInfoEXT validation_messenger(
    PFN_vkDebugUtilsMessengerCallbackEXT callback, void* user) {
  VkDebugUtilsMessengerCreateInfoEXT m{};
  m.sType = VK_STRUCTURE_TYPE_DEBUG_UTILS_MESSENGER_CREATE_INFO_EXT;
  m.messageSeverity = VK_DEBUG_UTILS_MESSAGE_SEVERITY_WARNING_BIT_EXT |
                      VK_DEBUG_UTILS_MESSAGE_SEVERITY_ERROR_BIT_EXT;
  m.messageType = VK_DEBUG_UTILS_MESSAGE_TYPE_GENERAL_BIT_EXT |
                  VK_DEBUG_UTILS_MESSAGE_TYPE_VALIDATION_BIT_EXT |
                  VK_DEBUG_UTILS_MESSAGE_TYPE_PERFORMANCE_BIT_EXT;
  m.pfnUserCallback = callback;
  m.pUserData = user;
  return m;
}

}  // namespace bisturi::render
