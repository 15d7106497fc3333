// The heap policy a rendering program sets (runtime/heap_policy.h): memory a thread frees at the
// top of its heap stays for its next allocations instead of going back to the kernel.

#include <gtest/gtest.h>
#include <sys/resource.h>
#include <unistd.h>

#include <cstring>
#include <memory>
#include <thread>
#include <vector>

#include "bisturi/runtime/heap_policy.h"

namespace bisturi::runtime {
namespace {

long minor_faults_of_this_thread() {
  rusage usage{};
  getrusage(RUSAGE_THREAD, &usage);
  return usage.ru_minflt;
}

/// On a thread of its own (its own heap, as the render thread has): fills `bytes` in blocks
/// small enough to come from the heap, frees them all, fills them again; the page faults of the
/// second fill.
long faults_to_fill_again(std::size_t bytes) {
  long faults = 0;
  std::thread([&] {
    constexpr std::size_t kBlock = 64 << 10;
    std::vector<std::unique_ptr<char[]>> blocks;
    const auto fill = [&] {
      for (std::size_t i = 0; i < bytes / kBlock; ++i) {
        blocks.emplace_back(new char[kBlock]);
        std::memset(blocks.back().get(), 1, kBlock);
      }
    };
    fill();
    blocks.clear();
    const long before = minor_faults_of_this_thread();
    fill();
    faults = minor_faults_of_this_thread() - before;
  }).join();
  return faults;
}

TEST(HeapPolicy, AThreadsFreedMemoryIsFilledAgainWithoutFaultingItIn) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizer's allocator, not glibc's, serves this build";
#endif
  // More than glibc's own trim threshold ever grows to (64 MiB): by default a thread gives the
  // top of its heap back (a third of this, on Debian 12), and faults it in again.
  constexpr std::size_t kBytes = std::size_t{96} << 20;
  const long pages = static_cast<long>(kBytes / static_cast<std::size_t>(sysconf(_SC_PAGESIZE)));
  const long faults_by_default = faults_to_fill_again(kBytes);
  EXPECT_GT(faults_by_default, pages / 4);
  ASSERT_TRUE(keep_freed_heap());
  const long faults_kept = faults_to_fill_again(kBytes);
  EXPECT_LT(faults_kept, pages / 100) << "by default: " << faults_by_default;
}

TEST(HeapPolicy, AThreadThatFaultedItsHeapInAllocatesWithoutFaults) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
  GTEST_SKIP() << "the sanitizer's allocator, not glibc's, serves this build";
#endif
  ASSERT_TRUE(keep_freed_heap());
  // More than any test before this one touched in a thread's heap (96 MiB): without the
  // prefault, most of these pages would be new to the heap and fault in as they are filled.
  constexpr std::size_t kBytes = std::size_t{128} << 20;
  const long pages = static_cast<long>(kBytes / static_cast<std::size_t>(sysconf(_SC_PAGESIZE)));
  long faults_prefaulting = 0, faults_filling = 0;
  std::thread([&] {
    const long start = minor_faults_of_this_thread();
    prefault_thread_heap(kBytes + (std::size_t{8} << 20));
    const long prefaulted = minor_faults_of_this_thread();
    faults_prefaulting = prefaulted - start;
    constexpr std::size_t kBlock = 64 << 10;
    std::vector<std::unique_ptr<char[]>> blocks;
    for (std::size_t i = 0; i < kBytes / kBlock; ++i) {
      blocks.emplace_back(new char[kBlock]);
      std::memset(blocks.back().get(), 1, kBlock);
    }
    faults_filling = minor_faults_of_this_thread() - prefaulted;
  }).join();
  EXPECT_LT(faults_filling, pages / 100) << "the prefault itself took " << faults_prefaulting;
}

}  // namespace
}  // namespace bisturi::runtime
