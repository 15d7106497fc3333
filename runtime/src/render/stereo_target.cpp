#include "stereo_target.h"

#include <array>

#include "bisturi/runtime/render/errors.h"

namespace bisturi::render::vk {

namespace {

VkFormat pick_depth_format(VkPhysicalDevice physical) {
  for (const VkFormat f : {VK_FORMAT_D32_SFLOAT, VK_FORMAT_X8_D24_UNORM_PACK32,
                           VK_FORMAT_D24_UNORM_S8_UINT, VK_FORMAT_D16_UNORM}) {
    VkFormatProperties props;
    vkGetPhysicalDeviceFormatProperties(physical, f, &props);
    if ((props.optimalTilingFeatures & VK_FORMAT_FEATURE_DEPTH_STENCIL_ATTACHMENT_BIT) != 0) {
      return f;
    }
  }
  throw RenderError("the Vulkan device has no depth format to render to");
}

}  // namespace

StereoTarget::StereoTarget(const Context& context, std::uint32_t width, std::uint32_t height)
    : context_(context), width_(width), height_(height) {
  try {
    create(kColourFormat, nullptr);
  } catch (...) {
    release();
    throw;
  }
}

StereoTarget::StereoTarget(const Context& context, std::uint32_t width, std::uint32_t height,
                           VkFormat view_format, const std::vector<VkImage>& images)
    : context_(context), width_(width), height_(height) {
  try {
    create(view_format, &images);
  } catch (...) {
    release();
    throw;
  }
}

void StereoTarget::create(VkFormat colour_format, const std::vector<VkImage>* external) {
  {
    const VkDevice device = context_.device();
    depth_format_ = pick_depth_format(context_.physical_device());
    if (external == nullptr) {
      colour_ = create_image(kColourFormat,
                             VK_IMAGE_USAGE_COLOR_ATTACHMENT_BIT | VK_IMAGE_USAGE_TRANSFER_SRC_BIT,
                             VK_IMAGE_ASPECT_COLOR_BIT);
    }
    depth_ = create_image(depth_format_, VK_IMAGE_USAGE_DEPTH_STENCIL_ATTACHMENT_BIT,
                          VK_IMAGE_ASPECT_DEPTH_BIT);

    std::array<VkAttachmentDescription, 2> attachments{};
    attachments[0].format = colour_format;
    attachments[0].samples = VK_SAMPLE_COUNT_1_BIT;
    attachments[0].loadOp = VK_ATTACHMENT_LOAD_OP_CLEAR;
    attachments[0].storeOp = VK_ATTACHMENT_STORE_OP_STORE;
    attachments[0].stencilLoadOp = VK_ATTACHMENT_LOAD_OP_DONT_CARE;
    attachments[0].stencilStoreOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    attachments[0].initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
    // Own image: ready to be copied out. A runtime's image: handed back as it was handed over.
    attachments[0].finalLayout = external == nullptr ? VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL
                                                     : VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL;
    attachments[1] = attachments[0];
    attachments[1].format = depth_format_;
    attachments[1].storeOp = VK_ATTACHMENT_STORE_OP_DONT_CARE;
    attachments[1].finalLayout = VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL;

    VkAttachmentReference colour_ref{0, VK_IMAGE_LAYOUT_COLOR_ATTACHMENT_OPTIMAL};
    VkAttachmentReference depth_ref{1, VK_IMAGE_LAYOUT_DEPTH_STENCIL_ATTACHMENT_OPTIMAL};
    VkSubpassDescription subpass{};
    subpass.pipelineBindPoint = VK_PIPELINE_BIND_POINT_GRAPHICS;
    subpass.colorAttachmentCount = 1;
    subpass.pColorAttachments = &colour_ref;
    subpass.pDepthStencilAttachment = &depth_ref;

    // In: the previous frame's copy out of the colour image and its depth writes finish before
    // this frame clears and draws. Out: the draws finish before the copy to the read-back buffer
    // (a runtime's image: before anything later on the queue, where the runtime reads it).
    std::array<VkSubpassDependency, 2> deps{};
    deps[0].srcSubpass = VK_SUBPASS_EXTERNAL;
    deps[0].dstSubpass = 0;
    deps[0].srcStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT |
                           VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT |
                           VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    deps[0].dstStageMask = VK_PIPELINE_STAGE_EARLY_FRAGMENT_TESTS_BIT |
                           VK_PIPELINE_STAGE_LATE_FRAGMENT_TESTS_BIT |
                           VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    deps[0].srcAccessMask =
        VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT | VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    deps[0].dstAccessMask = VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_READ_BIT |
                            VK_ACCESS_DEPTH_STENCIL_ATTACHMENT_WRITE_BIT |
                            VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    deps[1].srcSubpass = 0;
    deps[1].dstSubpass = VK_SUBPASS_EXTERNAL;
    deps[1].srcStageMask = VK_PIPELINE_STAGE_COLOR_ATTACHMENT_OUTPUT_BIT;
    deps[1].srcAccessMask = VK_ACCESS_COLOR_ATTACHMENT_WRITE_BIT;
    if (external == nullptr) {
      deps[1].dstStageMask = VK_PIPELINE_STAGE_TRANSFER_BIT;
      deps[1].dstAccessMask = VK_ACCESS_TRANSFER_READ_BIT;
    } else {
      deps[1].dstStageMask = VK_PIPELINE_STAGE_BOTTOM_OF_PIPE_BIT;
      deps[1].dstAccessMask = 0;
    }

    const std::uint32_t view_mask = 0b11;  // both eyes in one pass
    const std::uint32_t correlation_mask = 0b11;
    VkRenderPassMultiviewCreateInfo multiview{};
    multiview.sType = VK_STRUCTURE_TYPE_RENDER_PASS_MULTIVIEW_CREATE_INFO;
    multiview.subpassCount = 1;
    multiview.pViewMasks = &view_mask;
    multiview.correlationMaskCount = 1;
    multiview.pCorrelationMasks = &correlation_mask;

    VkRenderPassCreateInfo info{};
    info.sType = VK_STRUCTURE_TYPE_RENDER_PASS_CREATE_INFO;
    info.pNext = &multiview;
    info.attachmentCount = static_cast<std::uint32_t>(attachments.size());
    info.pAttachments = attachments.data();
    info.subpassCount = 1;
    info.pSubpasses = &subpass;
    info.dependencyCount = static_cast<std::uint32_t>(deps.size());
    info.pDependencies = deps.data();
    check(vkCreateRenderPass(device, &info, nullptr, &render_pass_), "vkCreateRenderPass");

    std::vector<VkImageView> colour_views;
    if (external == nullptr) {
      colour_views.push_back(colour_.view);
    } else {
      for (const VkImage image : *external) {
        external_views_.push_back(array_view(image, colour_format, VK_IMAGE_ASPECT_COLOR_BIT));
      }
      colour_views = external_views_;
    }
    for (const VkImageView colour : colour_views) {
      const std::array<VkImageView, 2> views{colour, depth_.view};
      VkFramebufferCreateInfo fb{};
      fb.sType = VK_STRUCTURE_TYPE_FRAMEBUFFER_CREATE_INFO;
      fb.renderPass = render_pass_;
      fb.attachmentCount = static_cast<std::uint32_t>(views.size());
      fb.pAttachments = views.data();
      fb.width = width_;
      fb.height = height_;
      fb.layers = 1;  // multiview: the layers come from the view mask
      VkFramebuffer framebuffer = VK_NULL_HANDLE;
      check(vkCreateFramebuffer(device, &fb, nullptr, &framebuffer), "vkCreateFramebuffer");
      framebuffers_.push_back(framebuffer);
    }
  }
}

VkImageView StereoTarget::array_view(VkImage image, VkFormat format,
                                     VkImageAspectFlags aspect) const {
  VkImageViewCreateInfo view{};
  view.sType = VK_STRUCTURE_TYPE_IMAGE_VIEW_CREATE_INFO;
  view.image = image;
  view.viewType = VK_IMAGE_VIEW_TYPE_2D_ARRAY;
  view.format = format;
  view.subresourceRange = {aspect, 0, 1, 0, 2};
  VkImageView out = VK_NULL_HANDLE;
  check(vkCreateImageView(context_.device(), &view, nullptr, &out), "vkCreateImageView");
  return out;
}

StereoTarget::~StereoTarget() {
  release();
}

void StereoTarget::release() {
  const VkDevice device = context_.device();
  for (const VkFramebuffer f : framebuffers_)
    vkDestroyFramebuffer(device, f, nullptr);
  framebuffers_.clear();
  for (const VkImageView v : external_views_)
    vkDestroyImageView(device, v, nullptr);
  external_views_.clear();
  if (render_pass_ != VK_NULL_HANDLE) vkDestroyRenderPass(device, render_pass_, nullptr);
  render_pass_ = VK_NULL_HANDLE;
  destroy(colour_);
  destroy(depth_);
}

StereoTarget::Image StereoTarget::create_image(VkFormat format, VkImageUsageFlags usage,
                                               VkImageAspectFlags aspect) {
  const VkDevice device = context_.device();
  Image out;
  VkImageCreateInfo info{};
  info.sType = VK_STRUCTURE_TYPE_IMAGE_CREATE_INFO;
  info.imageType = VK_IMAGE_TYPE_2D;
  info.format = format;
  info.extent = {width_, height_, 1};
  info.mipLevels = 1;
  info.arrayLayers = 2;
  info.samples = VK_SAMPLE_COUNT_1_BIT;
  info.tiling = VK_IMAGE_TILING_OPTIMAL;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  info.initialLayout = VK_IMAGE_LAYOUT_UNDEFINED;
  check(vkCreateImage(device, &info, nullptr, &out.image), "vkCreateImage");
  try {
    VkMemoryRequirements req;
    vkGetImageMemoryRequirements(device, out.image, &req);
    VkMemoryAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex =
        context_.memory_type(req.memoryTypeBits, VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    check(vkAllocateMemory(device, &alloc, nullptr, &out.memory), "vkAllocateMemory");
    check(vkBindImageMemory(device, out.image, out.memory, 0), "vkBindImageMemory");
    out.view = array_view(out.image, format, aspect);
  } catch (...) {
    destroy(out);
    throw;
  }
  return out;
}

void StereoTarget::destroy(Image& image) {
  const VkDevice device = context_.device();
  if (image.view != VK_NULL_HANDLE) vkDestroyImageView(device, image.view, nullptr);
  if (image.image != VK_NULL_HANDLE) vkDestroyImage(device, image.image, nullptr);
  if (image.memory != VK_NULL_HANDLE) vkFreeMemory(device, image.memory, nullptr);
  image = Image{};
}

}  // namespace bisturi::render::vk
