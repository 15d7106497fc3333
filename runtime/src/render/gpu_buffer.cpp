#include "gpu_buffer.h"

#include <utility>

namespace bisturi::render::vk {

Buffer::Buffer(const Context& context, VkDeviceSize size, VkBufferUsageFlags usage,
               HostAccess access)
    : device_(context.device()), size_(size) {
  VkBufferCreateInfo info{};
  info.sType = VK_STRUCTURE_TYPE_BUFFER_CREATE_INFO;
  info.size = size;
  info.usage = usage;
  info.sharingMode = VK_SHARING_MODE_EXCLUSIVE;
  check(vkCreateBuffer(device_, &info, nullptr, &buffer_), "vkCreateBuffer");
  try {
    VkMemoryRequirements req;
    vkGetBufferMemoryRequirements(device_, buffer_, &req);
    // Streams and indices: host-visible, device-local when the device has such memory (a GPU with
    // resizable BAR, or any CPU device); read-back: host-cached for fast reads.
    const VkMemoryPropertyFlags required = VK_MEMORY_PROPERTY_HOST_VISIBLE_BIT;
    const VkMemoryPropertyFlags preferred =
        access == HostAccess::Read ? VkMemoryPropertyFlags(VK_MEMORY_PROPERTY_HOST_CACHED_BIT |
                                                           VK_MEMORY_PROPERTY_HOST_COHERENT_BIT)
                                   : VkMemoryPropertyFlags(VK_MEMORY_PROPERTY_HOST_COHERENT_BIT |
                                                           VK_MEMORY_PROPERTY_DEVICE_LOCAL_BIT);
    const std::uint32_t type = context.memory_type(req.memoryTypeBits, required, preferred);
    coherent_ = (context.memory_flags(type) & VK_MEMORY_PROPERTY_HOST_COHERENT_BIT) != 0;
    VkMemoryAllocateInfo alloc{};
    alloc.sType = VK_STRUCTURE_TYPE_MEMORY_ALLOCATE_INFO;
    alloc.allocationSize = req.size;
    alloc.memoryTypeIndex = type;
    check(vkAllocateMemory(device_, &alloc, nullptr, &memory_), "vkAllocateMemory");
    check(vkBindBufferMemory(device_, buffer_, memory_, 0), "vkBindBufferMemory");
    check(vkMapMemory(device_, memory_, 0, VK_WHOLE_SIZE, 0, &mapped_), "vkMapMemory");
  } catch (...) {
    reset();
    throw;
  }
}

Buffer& Buffer::operator=(Buffer&& other) noexcept {
  if (this != &other) {
    reset();
    device_ = std::exchange(other.device_, VK_NULL_HANDLE);
    buffer_ = std::exchange(other.buffer_, VK_NULL_HANDLE);
    memory_ = std::exchange(other.memory_, VK_NULL_HANDLE);
    mapped_ = std::exchange(other.mapped_, nullptr);
    size_ = std::exchange(other.size_, 0);
    coherent_ = other.coherent_;
  }
  return *this;
}

void Buffer::reset() {
  if (device_ == VK_NULL_HANDLE) return;
  if (buffer_ != VK_NULL_HANDLE) vkDestroyBuffer(device_, buffer_, nullptr);
  if (memory_ != VK_NULL_HANDLE) vkFreeMemory(device_, memory_, nullptr);  // unmaps too
  buffer_ = VK_NULL_HANDLE;
  memory_ = VK_NULL_HANDLE;
  mapped_ = nullptr;
  size_ = 0;
  device_ = VK_NULL_HANDLE;
}

void Buffer::invalidate() const {
  if (coherent_ || memory_ == VK_NULL_HANDLE) return;
  VkMappedMemoryRange range{};
  range.sType = VK_STRUCTURE_TYPE_MAPPED_MEMORY_RANGE;
  range.memory = memory_;
  range.offset = 0;
  range.size = VK_WHOLE_SIZE;
  vkInvalidateMappedMemoryRanges(device_, 1, &range);
}

}  // namespace bisturi::render::vk
