#pragma once
// The render target of both eyes: a two-layer colour image and a two-layer depth image, and the
// multiview render pass (view mask 0b11) that draws into both layers at once.

#include <vulkan/vulkan.h>

#include <cstdint>

#include "vulkan_context.h"

namespace bisturi::render::vk {

class StereoTarget {
 public:
  static constexpr VkFormat kColourFormat = VK_FORMAT_R8G8B8A8_UNORM;

  StereoTarget(const Context& context, std::uint32_t width, std::uint32_t height);
  ~StereoTarget();
  StereoTarget(const StereoTarget&) = delete;
  StereoTarget& operator=(const StereoTarget&) = delete;

  [[nodiscard]] VkRenderPass render_pass() const { return render_pass_; }
  [[nodiscard]] VkFramebuffer framebuffer() const { return framebuffer_; }
  [[nodiscard]] VkImage colour_image() const { return colour_.image; }
  [[nodiscard]] std::uint32_t width() const { return width_; }
  [[nodiscard]] std::uint32_t height() const { return height_; }

 private:
  struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
  };
  Image create_image(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect);
  void destroy(Image& image);
  void release();

  const Context& context_;
  std::uint32_t width_;
  std::uint32_t height_;
  VkFormat depth_format_ = VK_FORMAT_D32_SFLOAT;
  Image colour_;
  Image depth_;
  VkRenderPass render_pass_ = VK_NULL_HANDLE;
  VkFramebuffer framebuffer_ = VK_NULL_HANDLE;
};

}  // namespace bisturi::render::vk
