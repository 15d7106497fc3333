#pragma once
// BigVector: std::vector for the large arrays of meshes and of their construction. Blocks of
// 1 MiB and more are 2 MiB aligned and advised as transparent huge pages, so filling a fresh
// array costs one page fault per 2 MiB instead of one per 4 KiB. On the virtual machines we
// measured, a page fault costs about 11 us: a 2M-triangle import spent most of its time in them.
// Smaller blocks come from operator new as usual.

#include <sys/mman.h>

#include <cstddef>
#include <cstdlib>
#include <new>
#include <vector>

namespace bisturi {

/// kWholePages: round blocks up to whole huge pages (faster to fill, up to 2 MiB more memory;
/// for short-lived scratch arrays). Otherwise only the whole huge pages inside a block are huge
/// and the tail keeps small pages, so no memory is wasted (for arrays that stay).
template <class T, bool kWholePages = false>
class HugePageAllocator {
 public:
  using value_type = T;
  template <class U>
  struct rebind {
    using other = HugePageAllocator<U, kWholePages>;
  };

  HugePageAllocator() noexcept = default;
  template <class U>
  HugePageAllocator(const HugePageAllocator<U, kWholePages>& /*other*/) noexcept {}

  T* allocate(std::size_t n) {
    std::size_t bytes = n * sizeof(T);
    if (bytes < kThreshold) return static_cast<T*>(::operator new(bytes));
    if (kWholePages) bytes = (bytes + kHugePage - 1) / kHugePage * kHugePage;
    void* p = nullptr;
    if (posix_memalign(&p, kHugePage, bytes) != 0) throw std::bad_alloc();
    // Advice only: where huge pages are off, this fails harmlessly and 4 KiB pages are used.
    (void)madvise(p, bytes, MADV_HUGEPAGE);
    return static_cast<T*>(p);
  }

  void deallocate(T* p, std::size_t n) noexcept {
    if (n * sizeof(T) < kThreshold) {
      ::operator delete(p);
    } else {
      std::free(p);
    }
  }

  template <class U>
  bool operator==(const HugePageAllocator<U, kWholePages>& /*other*/) const noexcept {
    return true;
  }

 private:
  static constexpr std::size_t kHugePage = std::size_t{2} << 20;
  static constexpr std::size_t kThreshold = std::size_t{1} << 20;
};

template <class T>
using BigVector = std::vector<T, HugePageAllocator<T>>;

/// For temporary arrays of a computation (mesh construction): whole huge pages.
template <class T>
using ScratchVector = std::vector<T, HugePageAllocator<T, true>>;

}  // namespace bisturi
