// The step's thread team (see step_threads.h).

#include "step_threads.h"

#include <algorithm>

namespace bisturi::sim {

namespace {

void relax() {
#if defined(__x86_64__) || defined(__i386__)
  __builtin_ia32_pause();
#endif
}

constexpr std::uint64_t kPartMask = 0xffffffffu;

}  // namespace

StepThreads::StepThreads(unsigned threads) : StepThreads(threads, kDefaultSpins, {}) {}

StepThreads::StepThreads(unsigned threads, unsigned spins, const std::function<void()>& on_start)
    : spins_(spins) {
  claim_.store(kPartMask, std::memory_order_relaxed);  // generation 0: no part to claim
  parts_ = std::max(1u, threads);
  for (unsigned t = 1; t < parts_; ++t)
    workers_.emplace_back([this, on_start] {
      if (on_start) on_start();
      work();
    });
}

StepThreads::StepThreads(unsigned parts, std::function<void()> after_part)
    : parts_(std::max(1u, parts)), after_part_(std::move(after_part)) {}

StepThreads::~StepThreads() {
  stop_.store(true, std::memory_order_release);
  claim_.fetch_add(std::uint64_t{1} << 32, std::memory_order_release);
  claim_.notify_all();
  for (std::thread& w : workers_)
    w.join();
}

void StepThreads::run(const std::function<void(unsigned)>& job) {
  if (sequential()) {
    for (unsigned t = 0; t < parts_; ++t) {
      job(t);
      after_part_();
    }
    return;
  }
  if (workers_.empty()) {
    job(0);
    return;
  }
  job_ = &job;
  unfinished_.store(size() - 1, std::memory_order_relaxed);
  // A new generation with part 1 next (part 0 is the caller's); the release publishes job_.
  const std::uint64_t generation = (claim_.load(std::memory_order_relaxed) >> 32) + 1;
  claim_.store((generation << 32) | 1u, std::memory_order_release);
  claim_.notify_all();
  job(0);
  run_claimed_parts();
  // Parts a helper claimed and is still running. The yield lets a helper that shares this
  // core finish instead of spinning through its time slice.
  for (unsigned spin = 0; unfinished_.load(std::memory_order_acquire) != 0; ++spin) {
    if (spin < 4096) {
      relax();
    } else {
      std::this_thread::yield();
    }
  }
}

void StepThreads::run_claimed_parts() {
  const unsigned parts = size();
  std::uint64_t c = claim_.load(std::memory_order_acquire);
  while ((c & kPartMask) < parts) {
    if (!claim_.compare_exchange_weak(c, c + 1, std::memory_order_acq_rel,
                                      std::memory_order_acquire))
      continue;
    // The claim succeeded: the job of this generation cannot end before this part is done, so
    // job_ is still its job.
    (*job_)(static_cast<unsigned>(c & kPartMask));
    unfinished_.fetch_sub(1, std::memory_order_release);
    c = claim_.load(std::memory_order_acquire);
  }
}

void StepThreads::work() {
  for (;;) {
    std::uint64_t c = claim_.load(std::memory_order_acquire);
    // Nothing to claim: spin a while (the passes of one step follow each other closely, and a
    // wake-up from sleep costs tens of microseconds), then sleep until the value changes.
    for (unsigned spin = 0;
         spin < spins_ && (c & kPartMask) >= size() && !stop_.load(std::memory_order_relaxed);
         ++spin) {
      relax();
      c = claim_.load(std::memory_order_acquire);
    }
    if (stop_.load(std::memory_order_acquire)) return;
    if ((c & kPartMask) >= size()) {
      claim_.wait(c, std::memory_order_acquire);
      continue;
    }
    run_claimed_parts();
  }
}

}  // namespace bisturi::sim
