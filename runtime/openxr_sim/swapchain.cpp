// Swapchains: real VkImages on the application's device (kept in COLOR_ATTACHMENT_OPTIMAL between
// acquire and release, as XR_KHR_vulkan_enable2 specifies), the acquire/wait/release cycle, and
// the read-back of a released image into host memory, which stands in for the compositor.

#include "../src/render/colour_image_barrier.h"
#include "api.h"

namespace bisturi::xrsim {

using render::colour_image_barrier;

namespace {

constexpr std::uint32_t kImages = 3;

Swapchain* checked(XrSwapchain handle_) {
  return object<Swapchain>(handle_);
}

std::uint32_t texel_bytes(VkFormat format) {
  return format == VK_FORMAT_R16G16B16A16_SFLOAT ? 8u : 4u;
}

VkImageUsageFlags vulkan_usage(XrSwapchainUsageFlags usage) {
  // TRANSFER_SRC always: the "compositor" copies from every image.
  VkImageUsageFlags flags = VK_IMAGE_USAGE_TRANSFER_SRC_BIT;
  if ((usage & XR_SWAPCHAIN_USAGE_COLOR_ATTACHMENT_BIT) != 0) {
    flags |= VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT;
  }
  if ((usage & XR_SWAPCHAIN_USAGE_TRANSFER_DST_BIT) != 0) flags |= VK_IMAGE_USAGE_TRANSFER_DST_BIT;
  if ((usage & XR_SWAPCHAIN_USAGE_SAMPLED_BIT) != 0) flags |= VK_IMAGE_USAGE_SAMPLED_BIT;
  if ((usage & XR_SWAPCHAIN_USAGE_UNORDERED_ACCESS_BIT) != 0) flags |= VK_IMAGE_USAGE_STORAGE_BIT;
  return flags;
}

void record_initial_layouts(VkCommandBuffer commands, void* user) {
  const auto& chain = *static_cast<const Swapchain*>(user);
  for (const VkImage image : chain.images) {
    colour_image_barrier(
        commands, image, VK_IMAGE_LAYOUT_UNDEFINED, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, 0,
        VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
        VK_PIPELINE_STAGE_TOP_OF_PIPE_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT, chain.array_size);
  }
}

struct ReadBack {
  Swapchain* chain;
  VkImage image;
  std::uint32_t layer;
};

std::string usage_names(XrSwapchainUsageFlags usage) {
  std::string out = "[";
  const auto add = [&](XrSwapchainUsageFlags bit, const char* name) {
    if ((usage & bit) == 0) return;
    if (out.size() > 1) out += ",";
    out += json_string(name);
  };
  add(XR_SWAPCHAIN_USAGE_COLOR_ATTACHMENT_BIT, "color_attachment");
  add(XR_SWAPCHAIN_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT, "depth_stencil_attachment");
  add(XR_SWAPCHAIN_USAGE_UNORDERED_ACCESS_BIT, "unordered_access");
  add(XR_SWAPCHAIN_USAGE_TRANSFER_SRC_BIT, "transfer_src");
  add(XR_SWAPCHAIN_USAGE_TRANSFER_DST_BIT, "transfer_dst");
  add(XR_SWAPCHAIN_USAGE_SAMPLED_BIT, "sampled");
  add(XR_SWAPCHAIN_USAGE_MUTABLE_FORMAT_BIT, "mutable_format");
  return out + "]";
}

void record_read_back(VkCommandBuffer commands, void* user) {
  const auto& r = *static_cast<const ReadBack*>(user);
  const std::uint32_t layers = r.chain->array_size;
  colour_image_barrier(commands, r.image, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL,
                       VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                       VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT | VK_ACCESS_TRANSFER_WRITE_BIT,
                       VK_ACCESS_TRANSFER_READ_BIT, VK_PIPELINE_STAGE_ALL_COMMANDS_BIT,
                       VK_PIPELINE_STAGE_TRANSFER_BIT, layers);
  VkBufferImageCopy region{};
  region.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, r.layer, 1};
  region.imageExtent = {r.chain->width, r.chain->height, 1};
  vkCmdCopyImageToBuffer(commands, r.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL, r.chain->readback,
                         1, &region);
  colour_image_barrier(commands, r.image, VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                       VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL, VK_ACCESS_TRANSFER_READ_BIT, 0,
                       VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT,
                       layers);
  VkBufferMemoryBarrier host{};
  host.sType = VK_STRUCTURE_TYPE_BUFFER_MEMORY_BARRIER;
  host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
  host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
  host.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  host.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  host.buffer = r.chain->readback;
  host.size = VK_WHOLE_SIZE;
  vkCmdPipelineBarrier(commands, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 0,
                       nullptr, 1, &host, 0, nullptr);
}

/// Images, memory and the read-back buffer; false on any Vulkan failure (the caller cleans up).
bool create_vulkan(Swapchain& chain, const XrSwapchainCreateInfo& info) {
  Session& s = *chain.session;
  const VkPhysicalDevice physical = s.instance->physical;
  for (std::uint32_t i = 0; i < kImages; ++i) {
    VkImageCreateInfo image{};
    image.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
    image.imageType = VK_IMAGE_TYPE_2D;
    image.format = chain.format;
    image.extent = {chain.width, chain.height, 1};
    image.mipLevels = 1;
    image.arrayLayers = chain.array_size;
    image.samples = VK_SAMPLE_COUNT_1_BIT;
    image.tiling = VK_IMAGE_TILING_OPTIMAL;
    image.usage = vulkan_usage(info.usageFlags);
    image.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
    image.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    if ((info.usageFlags & XR_SWAPCHAIN_USAGE_MUTABLE_FORMAT_BIT) != 0) {
      image.flags = VK_IMAGE_CREATE_MUTABLE_FORMAT_BIT;
    }
    VkImage created = VK_NULL_HANDLE;
    if (vkCreateImage(s.device, &image, nullptr, &created) != VK_SUCCESS) return false;
    chain.images.push_back(created);
    VkMemoryRequirements needs;
    vkGetImageMemoryRequirements(s.device, created, &needs);
    VkMemoryAllocateInfo allocate{};
    allocate.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    allocate.allocationSize = needs.size;
    allocate.memoryTypeIndex =
        memory_type(physical, needs.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    VkDeviceMemory memory = VK_NULL_HANDLE;
    if (allocate.memoryTypeIndex == UINT32_MAX ||
        vkAllocateMemory(s.device, &allocate, nullptr, &memory) != VK_SUCCESS) {
      return false;
    }
    chain.memory.push_back(memory);
    if (vkBindImageMemory(s.device, created, memory, 0) != VK_SUCCESS) return false;
  }
  VkBufferCreateInfo buffer{};
  buffer.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  buffer.size = VkDeviceSize{chain.width} * chain.height * texel_bytes(chain.format);
  buffer.usage = VK_BUFFER_USAGE_TRANSFER_DST_BIT;
  if (vkCreateBuffer(s.device, &buffer, nullptr, &chain.readback) != VK_SUCCESS) return false;
  VkMemoryRequirements needs;
  vkGetBufferMemoryRequirements(s.device, chain.readback, &needs);
  VkMemoryAllocateInfo allocate{};
  allocate.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
  allocate.allocationSize = needs.size;
  allocate.memoryTypeIndex =
      memory_type(physical, needs.memoryTypeBits,
                  VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT | VK_MEMORY_PROPERTY_HOST_COHERENT_BIT);
  if (allocate.memoryTypeIndex == UINT32_MAX ||
      vkAllocateMemory(s.device, &allocate, nullptr, &chain.readback_memory) != VK_SUCCESS ||
      vkBindBufferMemory(s.device, chain.readback, chain.readback_memory, 0) != VK_SUCCESS ||
      vkMapMemory(s.device, chain.readback_memory, 0, VK_WHOLE_SIZE, 0, &chain.mapped) !=
          VK_SUCCESS) {
    return false;
  }
  return run_commands(s, record_initial_layouts, &chain);
}

}  // namespace

bool read_back(Swapchain& swapchain, std::uint32_t image, std::uint32_t layer) {
  ReadBack r{&swapchain, swapchain.images[image], layer};
  return run_commands(*swapchain.session, record_read_back, &r);
}

void destroy_swapchain(Swapchain* chain) {
  Session& s = *chain->session;
  vkQueueWaitIdle(s.queue);
  if (chain->mapped != nullptr) vkUnmapMemory(s.device, chain->readback_memory);
  if (chain->readback != VK_NULL_HANDLE) vkDestroyBuffer(s.device, chain->readback, nullptr);
  if (chain->readback_memory != VK_NULL_HANDLE) {
    vkFreeMemory(s.device, chain->readback_memory, nullptr);
  }
  for (const VkImage image : chain->images)
    vkDestroyImage(s.device, image, nullptr);
  for (const VkDeviceMemory memory : chain->memory)
    vkFreeMemory(s.device, memory, nullptr);
  auto& list = s.swapchains;
  for (auto it = list.begin(); it != list.end(); ++it) {
    if (*it == chain) {
      list.erase(it);
      break;
    }
  }
  untrack(chain);
  delete chain;
}

XrResult EnumerateSwapchainFormats(XrSession handle_, std::uint32_t capacity, std::uint32_t* count,
                                   std::int64_t* formats) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  const auto& offered = s->instance->config.formats;
  *count = static_cast<std::uint32_t>(offered.size());
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < offered.size()) return XR_ERROR_SIZE_INSUFFICIENT;
  for (std::size_t i = 0; i < offered.size(); ++i)
    formats[i] = offered[i];
  return XR_SUCCESS;
}

XrResult CreateSwapchain(XrSession handle_, const XrSwapchainCreateInfo* info,
                         XrSwapchain* swapchain) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || swapchain == nullptr || info->type != XR_TYPE_SWAPCHAIN_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  bool offered = false;
  for (const VkFormat f : s->instance->config.formats)
    offered = offered || f == info->format;
  if (!offered) return XR_ERROR_SWAPCHAIN_FORMAT_UNSUPPORTED;
  // 2D images of one layer (one swapchain per eye) or two (one layer per eye).
  if (info->sampleCount != 1 || info->faceCount != 1 || info->arraySize < 1 ||
      info->arraySize > 2 || info->mipCount != 1) {
    return XR_ERROR_FEATURE_UNSUPPORTED;
  }
  const std::uint32_t max = s->instance->config.max_eye_size;
  if (info->width == 0 || info->height == 0 || info->width > max || info->height > max) {
    return XR_ERROR_SIZE_INSUFFICIENT;
  }
  auto* chain = new Swapchain();
  chain->session = s;
  chain->format = static_cast<VkFormat>(info->format);
  chain->width = info->width;
  chain->height = info->height;
  chain->array_size = info->arraySize;
  chain->usage = info->usageFlags;
  s->swapchains.push_back(chain);
  track(chain);
  if (!create_vulkan(*chain, *info)) {
    destroy_swapchain(chain);
    return XR_ERROR_RUNTIME_FAILURE;
  }
  s->instance->log.write("swapchain", "\"width\":" + std::to_string(chain->width) +
                                          ",\"height\":" + std::to_string(chain->height) +
                                          ",\"format\":" + json_string(format_name(chain->format)) +
                                          ",\"images\":" + std::to_string(kImages) +
                                          ",\"array_size\":" + std::to_string(chain->array_size) +
                                          ",\"usage\":" + usage_names(chain->usage));
  *swapchain = handle<XrSwapchain>(chain);
  return XR_SUCCESS;
}

XrResult DestroySwapchain(XrSwapchain handle_) {
  Swapchain* chain = checked(handle_);
  if (chain == nullptr) return XR_ERROR_HANDLE_INVALID;
  destroy_swapchain(chain);
  return XR_SUCCESS;
}

XrResult EnumerateSwapchainImages(XrSwapchain handle_, std::uint32_t capacity, std::uint32_t* count,
                                  XrSwapchainImageBaseHeader* images) {
  Swapchain* chain = checked(handle_);
  if (chain == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *count = static_cast<std::uint32_t>(chain->images.size());
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < chain->images.size()) return XR_ERROR_SIZE_INSUFFICIENT;
  auto* vulkan = reinterpret_cast<XrSwapchainImageVulkan2KHR*>(images);
  for (std::size_t i = 0; i < chain->images.size(); ++i) {
    if (vulkan[i].type != XR_TYPE_SWAPCHAIN_IMAGE_VULKAN2_KHR) return XR_ERROR_VALIDATION_FAILURE;
    vulkan[i].image = chain->images[i];
  }
  return XR_SUCCESS;
}

XrResult AcquireSwapchainImage(XrSwapchain handle_, const XrSwapchainImageAcquireInfo* /*info*/,
                               std::uint32_t* index) {
  Swapchain* chain = checked(handle_);
  if (chain == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (index == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  if (chain->acquired.size() >= chain->images.size()) return XR_ERROR_CALL_ORDER_INVALID;
  *index = chain->next_image;
  chain->acquired.push_back(chain->next_image);
  chain->next_image = (chain->next_image + 1) % static_cast<std::uint32_t>(chain->images.size());
  return XR_SUCCESS;
}

XrResult WaitSwapchainImage(XrSwapchain handle_, const XrSwapchainImageWaitInfo* info) {
  Swapchain* chain = checked(handle_);
  if (chain == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || info->type != XR_TYPE_SWAPCHAIN_IMAGE_WAIT_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (chain->acquired.empty() || chain->waited) return XR_ERROR_CALL_ORDER_INVALID;
  // The compositor reads images synchronously at xrEndFrame, so they are never busy here.
  chain->waited = true;
  return XR_SUCCESS;
}

XrResult ReleaseSwapchainImage(XrSwapchain handle_, const XrSwapchainImageReleaseInfo* /*info*/) {
  Swapchain* chain = checked(handle_);
  if (chain == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (chain->acquired.empty() || !chain->waited) return XR_ERROR_CALL_ORDER_INVALID;
  chain->released = chain->acquired.front();
  chain->acquired.pop_front();
  chain->waited = false;
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
