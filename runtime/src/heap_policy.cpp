// The heap's policy for giving memory back (see heap_policy.h).
#include "bisturi/runtime/heap_policy.h"

#include <malloc.h>
#include <unistd.h>

#include <cstdlib>
#include <vector>

namespace bisturi::runtime {

bool keep_freed_heap() {
  // The trim threshold holds for every thread's heap, not only the main one; the mmap threshold
  // (at glibc's largest) keeps the frames' big blocks in the heap too, where they are reused.
  constexpr int kTrimThreshold = 1 << 30;
  constexpr int kMmapThreshold = 32 << 20;
  const bool trim = mallopt(M_TRIM_THRESHOLD, kTrimThreshold) == 1;
  const bool mmap = mallopt(M_MMAP_THRESHOLD, kMmapThreshold) == 1;
  return trim && mmap;
}

void prefault_thread_heap(std::size_t bytes) {
  // Blocks under glibc's default mmap threshold, so they come from the thread's heap and not
  // from mappings of their own (which free would unmap).
  constexpr std::size_t kBlock = 64 << 10;
  const long page = sysconf(_SC_PAGESIZE);
  const std::size_t step = page > 0 ? static_cast<std::size_t>(page) : 4096;
  std::vector<void*> blocks;
  blocks.reserve(bytes / kBlock + 1);
  for (std::size_t done = 0; done < bytes; done += kBlock) {
    void* block = std::malloc(kBlock);
    if (block == nullptr) break;
    // A write to every page faults it in; volatile, so the block is not optimised away.
    auto* bytes_of = static_cast<volatile unsigned char*>(block);
    for (std::size_t at = 0; at < kBlock; at += step)
      bytes_of[at] = 0;
    blocks.push_back(block);
  }
  for (void* block : blocks)
    std::free(block);
}

}  // namespace bisturi::runtime
