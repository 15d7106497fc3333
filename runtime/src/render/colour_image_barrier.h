#pragma once
// A layout transition of a colour image (its first `layers` layers), as the renderer and the
// simulated runtime record around their copies (header-only: the simulated runtime is a separate
// module).

#include <vulkan/vulkan.h>

#include <cstdint>

namespace bisturi::render {

inline void colour_image_barrier(VkCommandBuffer commands, VkImage image, VkImageLayout from,
                                 VkImageLayout to, VkAccessFlags src_access,
                                 VkAccessFlags dst_access, VkPipelineStageFlags src_stage,
                                 VkPipelineStageFlags dst_stage, std::uint32_t layers = 1) {
  VkImageMemoryBarrier b{};
  b.sType = VK_STRUCTURE_TYPE_IMAGE_MEMORY_BARRIER;
  b.srcAccessMask = src_access;
  b.dstAccessMask = dst_access;
  b.oldLayout = from;
  b.newLayout = to;
  b.srcQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.dstQueueFamilyIndex = VK_QUEUE_FAMILY_IGNORED;
  b.image = image;
  b.subresourceRange = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 1, 0, layers};
  vkCmdPipelineBarrier(commands, src_stage, dst_stage, 0, 0, nullptr, 0, nullptr, 1, &b);
}

}  // namespace bisturi::render
