// The OpenXR sink's Vulkan side: the one instance and device, made through the runtime
// (XR_KHR_vulkan_enable2) and shared with the renderer; the two-layer swapchain the renderer draws
// into; the teardown (see openxr_sink_impl.h).

#include "openxr_sink_impl.h"

namespace bisturi::render {

namespace {

std::uint32_t vulkan_version(XrVersion v) {
  return VK_MAKE_API_VERSION(0, XR_VERSION_MAJOR(v), XR_VERSION_MINOR(v), 0);
}

}  // namespace

void OpenXrSink::Impl::create_vulkan() {
  XrGraphicsRequirementsVulkan2KHR requirements{};
  requirements.type = XR_TYPE_GRAPHICS_REQUIREMENTS_VULKAN2_KHR;
  xr_setup(get_requirements(instance, system, &requirements),
           "xrGetVulkanGraphicsRequirements2KHR");
  // The renderer needs Vulkan 1.2 (multiview, and the features it names).
  if (vulkan_version(requirements.maxApiVersionSupported) < VK_API_VERSION_1_2 &&
      XR_VERSION_MAJOR(requirements.maxApiVersionSupported) == 1) {
    throw XrUnavailable("the OpenXR runtime " + runtime + " takes Vulkan up to 1." +
                        std::to_string(XR_VERSION_MINOR(requirements.maxApiVersionSupported)) +
                        " only; the renderer needs 1.2" + kFallback);
  }
  vk::RuntimeCreation through;
  through.create_instance = [this](const VkInstanceCreateInfo& info) {
    XrVulkanInstanceCreateInfoKHR xr_info{};
    xr_info.type = XR_TYPE_VULKAN_INSTANCE_CREATE_INFO_KHR;
    xr_info.systemId = system;
    xr_info.pfnGetInstanceProcAddr = &vkGetInstanceProcAddr;
    xr_info.vulkanCreateInfo = &info;
    VkInstance made = VK_NULL_HANDLE;
    VkResult vk_result = VK_SUCCESS;
    const XrResult r = create_vk_instance(instance, &xr_info, &made, &vk_result);
    if (XR_FAILED(r) || vk_result != VK_SUCCESS) {
      unavailable(
          std::string("xrCreateVulkanInstanceKHR, vkCreateInstance: ") + vk::result_name(vk_result),
          r);
    }
    return made;
  };
  through.physical_device = [this](VkInstance vk_instance) {
    XrVulkanGraphicsDeviceGetInfoKHR info{};
    info.type = XR_TYPE_VULKAN_GRAPHICS_DEVICE_GET_INFO_KHR;
    info.systemId = system;
    info.vulkanInstance = vk_instance;
    VkPhysicalDevice physical = VK_NULL_HANDLE;
    xr_setup(get_vk_device(instance, &info, &physical), "xrGetVulkanGraphicsDevice2KHR");
    return physical;
  };
  through.create_device = [this](VkPhysicalDevice physical, const VkDeviceCreateInfo& info) {
    XrVulkanDeviceCreateInfoKHR xr_device{};
    xr_device.type = XR_TYPE_VULKAN_DEVICE_CREATE_INFO_KHR;
    xr_device.systemId = system;
    xr_device.pfnGetInstanceProcAddr = &vkGetInstanceProcAddr;
    xr_device.vulkanPhysicalDevice = physical;
    xr_device.vulkanCreateInfo = &info;
    VkDevice made = VK_NULL_HANDLE;
    VkResult vk_result = VK_SUCCESS;
    const XrResult r = create_vk_device(instance, &xr_device, &made, &vk_result);
    if (XR_FAILED(r) || vk_result != VK_SUCCESS) {
      unavailable(
          std::string("xrCreateVulkanDeviceKHR, vkCreateDevice: ") + vk::result_name(vk_result), r);
    }
    return made;
  };
  try {
    context = std::make_shared<vk::Context>(options.validation, through);
  } catch (const NoVulkanDevice& e) {
    throw XrUnavailable("the Vulkan device the OpenXR runtime " + runtime +
                        " shows frames from cannot be rendered on (" + e.what() + ")" + kFallback);
  }
}

void OpenXrSink::Impl::make_swapchain(std::uint32_t w, std::uint32_t h) {
  if (w > max_width || h > max_height || w == 0 || h == 0) {
    throw XrUnavailable("the eye size " + std::to_string(w) + "x" + std::to_string(h) +
                        " is not one the OpenXR runtime " + runtime + " takes (at most " +
                        std::to_string(max_width) + "x" + std::to_string(max_height) + ")" +
                        kFallback);
  }
  XrSwapchainCreateInfo info{};
  info.type = XR_TYPE_SWAPCHAIN_CREATE_INFO;
  // Drawn into as a colour attachment through a UNORM view; never copied into.
  info.usageFlags = XR_SWAPCHAIN_USAGE_COLOR_ATTACHMENT_BIT | XR_SWAPCHAIN_USAGE_MUTABLE_FORMAT_BIT;
  info.format = format;
  info.sampleCount = 1;
  info.width = w;
  info.height = h;
  info.faceCount = 1;
  info.arraySize = 2;  // left eye in layer 0, right in layer 1: one multiview pass draws both
  info.mipCount = 1;
  xr_setup(xrCreateSwapchain(session, &info, &swapchain), "xrCreateSwapchain");
  std::uint32_t count = 0;
  xr_setup(xrEnumerateSwapchainImages(swapchain, 0, &count, nullptr), "xrEnumerateSwapchainImages");
  XrSwapchainImageVulkan2KHR blank{};
  blank.type = XR_TYPE_SWAPCHAIN_IMAGE_VULKAN2_KHR;
  std::vector<XrSwapchainImageVulkan2KHR> listed(count, blank);
  xr_setup(xrEnumerateSwapchainImages(swapchain, count, &count,
                                      reinterpret_cast<XrSwapchainImageBaseHeader*>(listed.data())),
           "xrEnumerateSwapchainImages");
  images.clear();
  for (const XrSwapchainImageVulkan2KHR& image : listed)
    images.push_back(image.image);
  width = w;
  height = h;
  ++swapchain_generation;
}

void OpenXrSink::Impl::destroy_swapchain() {
  if (swapchain == XR_NULL_HANDLE) return;
  if (before_swapchain_destroyed) before_swapchain_destroyed();
  if (context) vkDeviceWaitIdle(context->device());
  xrDestroySwapchain(swapchain);
  swapchain = XR_NULL_HANDLE;
  images.clear();
  image_acquired = false;
  ++swapchain_generation;
}

void OpenXrSink::Impl::finish() {
  if (session != XR_NULL_HANDLE && !stopped) {
    // End the session the way the specification asks: request the exit, end it at STOPPING.
    const auto quiet_poll = [this] {
      try {
        poll_events();
      } catch (const RenderError&) {
        running = false;  // xrEndSession failed: the session is destroyed below all the same
      }
    };
    if (running && XR_SUCCEEDED(xrRequestExitSession(session))) {
      for (int i = 0; i < 500 && running; ++i) {
        quiet_poll();
        if (running) std::this_thread::sleep_for(std::chrono::milliseconds(2));
      }
      quiet_poll();  // IDLE and EXITING follow xrEndSession
    }
    stop("the session ended");
  }
}

void OpenXrSink::Impl::release() {
  finish();
  if (session != XR_NULL_HANDLE) destroy_session();
  // The device and instance the runtime made are the application's to destroy, after the
  // session; the renderer may still hold the context (it goes with the last holder).
  context.reset();
  if (instance != XR_NULL_HANDLE) xrDestroyInstance(instance);
  instance = XR_NULL_HANDLE;
  if (views_log != nullptr) std::fclose(views_log);
  views_log = nullptr;
}

}  // namespace bisturi::render
