#pragma once
// Internal: fresh memory that is about to be written in full is mapped in one system call
// (MADV_POPULATE_WRITE, Linux 5.14) instead of one page fault per 4 KiB page. In the virtual
// machines we measured a fault costs about 12 us, the call and the first write together about
// 3 us a page; the construction's arrays are written whole right after they are allocated, so
// nothing is mapped in vain. Elsewhere (an older kernel, another system) the call fails or is
// skipped: faults as usual.

#include <sys/mman.h>
#include <unistd.h>

#include <cstddef>
#include <cstdint>

namespace bisturi::construction {

/// Maps the whole pages of [data, data + bytes) for writing, as far as the system allows.
inline void prefault(const void* data, std::size_t bytes) {
#ifdef MADV_POPULATE_WRITE
  static const auto page = static_cast<std::uintptr_t>(::sysconf(_SC_PAGESIZE));
  const auto at = reinterpret_cast<std::uintptr_t>(data);
  const std::uintptr_t begin = (at + page - 1) & ~(page - 1);
  const std::uintptr_t end = (at + bytes) & ~(page - 1);
  // Below a few pages the faults cost less than the call.
  if (end < begin + 4 * page) return;
  (void)::madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_WRITE);
#else
  (void)data;
  (void)bytes;
#endif
}

/// v.reserve(n) with the new storage mapped for writing (for an empty v about to be filled).
template <class Vector>
void reserve_mapped(Vector& v, std::size_t n) {
  v.reserve(n);
  prefault(v.data(), n * sizeof(typename Vector::value_type));
}

/// Room for n elements of `bytes_each`, rounded up to whole 2 MiB pages where that adds at most
/// a sixteenth: a BigVector's tail then maps as one huge page too (one fault for 512).
inline std::size_t whole_huge_pages(std::size_t n, std::size_t bytes_each) {
  constexpr std::size_t kHugePage = std::size_t{2} << 20;
  const std::size_t bytes = n * bytes_each;
  const std::size_t whole = (bytes + kHugePage - 1) / kHugePage * kHugePage;
  return whole - bytes <= bytes / 16 ? whole / bytes_each : n;
}

}  // namespace bisturi::construction
