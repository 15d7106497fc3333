#pragma once
// A Vulkan buffer in host-visible memory, mapped for its whole life (vertex streams, index
// buffers, uniforms, read-back of frames).

#include <vulkan/vulkan.h>

#include <cstddef>

#include "vulkan_context.h"

namespace bisturi::render::vk {

enum class HostAccess { Write, Read };

class Buffer {
 public:
  Buffer() = default;
  Buffer(const Context& context, VkDeviceSize size, VkBufferUsageFlags usage,
         HostAccess access = HostAccess::Write);
  ~Buffer() { reset(); }
  Buffer(Buffer&& other) noexcept { *this = std::move(other); }
  Buffer& operator=(Buffer&& other) noexcept;
  Buffer(const Buffer&) = delete;
  Buffer& operator=(const Buffer&) = delete;

  void reset();
  [[nodiscard]] VkBuffer handle() const { return buffer_; }
  [[nodiscard]] VkDeviceSize size() const { return size_; }
  [[nodiscard]] std::byte* data() const { return static_cast<std::byte*>(mapped_); }
  /// Makes device writes visible to the host (non-coherent memory only).
  void invalidate() const;

 private:
  VkDevice device_ = VK_NULL_HANDLE;
  VkBuffer buffer_ = VK_NULL_HANDLE;
  VkDeviceMemory memory_ = VK_NULL_HANDLE;
  void* mapped_ = nullptr;
  VkDeviceSize size_ = 0;
  bool coherent_ = true;
};

}  // namespace bisturi::render::vk
