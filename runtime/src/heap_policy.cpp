// The heap's policy for giving memory back (see heap_policy.h).
#include "bisturi/runtime/heap_policy.h"

#include <malloc.h>

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

}  // namespace bisturi::runtime
