// The OpenXR sink's Vulkan side: its own device made through the runtime, the swapchain images,
// the staging upload of each frame and the teardown (see openxr_sink_impl.h).

#include "colour_image_barrier.h"
#include "openxr_sink_impl.h"
#include "vulkan_validation.h"

namespace bisturi::render {

namespace xr_detail {

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

}  // namespace xr_detail

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
  std::uint32_t api = VK_API_VERSION_1_1;  // enough for copies; the runtime may ask for more
  api = std::max(api, vulkan_version(requirements.minApiVersionSupported));

  VkApplicationInfo app{};
  app.sType = VK_STRUCTURE_TYPE_APPLICATION_INFO;
  app.pApplicationName = options.application_name.c_str();
  app.pEngineName = "bisturi";
  app.apiVersion = api;
  std::vector<const char*> layers, extensions;
  VkDebugUtilsMessengerCreateInfoEXT messenger_info =
      validation_messenger(on_validation, &validation);
  if (options.validation) add_validation(layers, extensions);
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
    colour_image_barrier(commands, image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                         VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 0, VK_ACCESS_TRANSFER_WRITE_BIT,
                         VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, VK_PIPELINE_STAGE_TRANSFER_BIT);
    VkBufferImageCopy region{};
    region.bufferOffset = static_cast<VkDeviceSize>(e * eye_bytes);
    region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 1};
    region.imageExtent = {width, height, 1};
    vkCmdCopyBufferToImage(commands, staging, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL, 1,
                           &region);
    colour_image_barrier(commands, image, VK_IMAGE_LAYOUT_TRANSFER_DST_OPTIMAL,
                         VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_ACCESS_TRANSFER_WRITE_BIT,
                         VK_ACCESS_COLOR_ATTACHMENT_READ_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT,
                         VK_PIPELINE_STAGE_TRANSFER_BIT,
                         VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT);
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

}  // namespace bisturi::render
