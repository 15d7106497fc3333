#pragma once
// The render target of both eyes: a two-layer colour image and a two-layer depth image, and the
// multiview render pass (view mask 0b11) that draws into both layers at once. The colour image is
// the target's own (read back for files) or, for a headset, each of an OpenXR runtime's
// two-layer swapchain images (one framebuffer per image, drawn straight into, left in
// COLOR_ATTACHMENT_OPTIMAL as XR_KHR_vulkan_enable2 hands them back).

#include <vulkan/vulkan.h>

#include <cstdint>
#include <vector>

#include "vulkan_context.h"

namespace bisturi::render::vk {

class StereoTarget {
 public:
  static constexpr VkFormat kColourFormat = VK_FORMAT_R8G8B8A8_UNORM;

  StereoTarget(const Context& context, std::uint32_t width, std::uint32_t height);
  /// Draws into `images` (two layers each, made by someone else on this device), seen through
  /// views of `view_format`.
  StereoTarget(const Context& context, std::uint32_t width, std::uint32_t height,
               VkFormat view_format, const std::vector<VkImage>& images);
  ~StereoTarget();
  StereoTarget(const StereoTarget&) = delete;
  StereoTarget& operator=(const StereoTarget&) = delete;

  [[nodiscard]] VkRenderPass render_pass() const { return render_pass_; }
  /// The framebuffer of the own image (0), or of external image `image`.
  [[nodiscard]] VkFramebuffer framebuffer(std::size_t image = 0) const {
    return framebuffers_[image];
  }
  [[nodiscard]] bool external() const { return !external_views_.empty(); }
  [[nodiscard]] VkImage colour_image() const { return colour_.image; }
  [[nodiscard]] std::uint32_t width() const { return width_; }
  [[nodiscard]] std::uint32_t height() const { return height_; }

 private:
  struct Image {
    VkImage image = VK_NULL_HANDLE;
    VkDeviceMemory memory = VK_NULL_HANDLE;
    VkImageView view = VK_NULL_HANDLE;
  };
  void create(VkFormat colour_format, const std::vector<VkImage>* external);
  Image create_image(VkFormat format, VkImageUsageFlags usage, VkImageAspectFlags aspect);
  VkImageView array_view(VkImage image, VkFormat format, VkImageAspectFlags aspect) const;
  void destroy(Image& image);
  void release();

  const Context& context_;
  std::uint32_t width_;
  std::uint32_t height_;
  VkFormat depth_format_ = VK_FORMAT_D32_SFLOAT;
  Image colour_;
  Image depth_;
  VkRenderPass render_pass_ = VK_NULL_HANDLE;
  std::vector<VkImageView> external_views_;
  std::vector<VkFramebuffer> framebuffers_;
};

}  // namespace bisturi::render::vk
