#pragma once
// The graphics pipeline of solids and instruments (shaders/mesh.vert, shaders/mesh.frag, embedded
// as SPIR-V): interleaved position and normal, depth test. Two variants: back faces culled
// (closed solids; counter-clockwise is front, with the y-flipped projection of headset.h) and
// two-sided (open solids: the fragment shader shades back faces as the tissue's inside).

#include <vulkan/vulkan.h>

#include <glm/mat4x4.hpp>
#include <glm/vec4.hpp>

#include "vulkan_context.h"

namespace bisturi::render::vk {

/// The push constants of one draw (shaders' `Draw` block).
struct DrawConstants {
  glm::mat4 model{1.0f};
  glm::vec4 colour{1.0f};
  glm::vec4 material{0.35f, 0.65f, 0.25f, 32.0f};
  glm::vec4 interior{0.42f, 0.06f, 0.05f, 0.0f};
};

/// The uniform block of one frame (shaders' `Eyes` block).
struct EyeUniforms {
  glm::mat4 view_projection[2];
  glm::vec4 eye_position[2];
  glm::vec4 light_direction;
  glm::vec4 lamp;  ///< the field lamp's focus (world mm), w = 1 when on
};

class MeshPipeline {
 public:
  MeshPipeline(const Context& context, VkRenderPass render_pass, std::uint32_t width,
               std::uint32_t height);
  ~MeshPipeline();
  MeshPipeline(const MeshPipeline&) = delete;
  MeshPipeline& operator=(const MeshPipeline&) = delete;

  [[nodiscard]] VkPipeline pipeline() const { return pipeline_; }
  [[nodiscard]] VkPipeline two_sided() const { return two_sided_; }
  [[nodiscard]] VkPipelineLayout layout() const { return layout_; }
  [[nodiscard]] VkDescriptorSetLayout set_layout() const { return set_layout_; }

 private:
  void release();

  VkDevice device_;
  VkDescriptorSetLayout set_layout_ = VK_NULL_HANDLE;
  VkPipelineLayout layout_ = VK_NULL_HANDLE;
  VkPipeline pipeline_ = VK_NULL_HANDLE;
  VkPipeline two_sided_ = VK_NULL_HANDLE;
};

}  // namespace bisturi::render::vk
