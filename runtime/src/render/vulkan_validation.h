#pragma once
// Turning on VK_LAYER_KHRONOS_validation for an instance, shared by the renderer's context and the
// OpenXR sink's own device: the layer check, the extension, and the debug messenger's settings.

#include <vulkan/vulkan.h>

#include <vector>

namespace bisturi::render {

/// Whether the Vulkan loader lists an instance layer of that name.
bool has_layer(const char* name);

/// Adds the validation layer and VK_EXT_debug_utils; throws RenderError (naming the Debian
/// package) when the layer is not installed.
void add_validation(std::vector<const char*>& layers, std::vector<const char*>& extensions);

/// A messenger for warnings and errors of every type, calling `callback` with `user`.
VkDebugUtilsMessengerCreateInfoEXT validation_messenger(
    PFN_vkDebugUtilsMessengerCallbackEXT callback, void* user);

}  // namespace bisturi::render
