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

}  // namespace

StepThreads::StepThreads(unsigned threads) {
  for (unsigned t = 1; t < std::max(1u, threads); ++t)
    workers_.emplace_back([this, t] { work(t); });
}

StepThreads::~StepThreads() {
  stop_.store(true, std::memory_order_release);
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_all();
  for (std::thread& w : workers_)
    w.join();
}

void StepThreads::run(const std::function<void(unsigned)>& job) {
  if (workers_.empty()) {
    job(0);
    return;
  }
  job_ = &job;
  pending_.store(static_cast<unsigned>(workers_.size()), std::memory_order_relaxed);
  generation_.fetch_add(1, std::memory_order_release);
  generation_.notify_all();
  job(0);
  while (pending_.load(std::memory_order_acquire) != 0)
    relax();
}

void StepThreads::work(unsigned member) {
  std::uint32_t seen = 0;
  for (;;) {
    // About 50-100 us of spinning before sleeping: the passes of one step follow each other
    // closely, and a wake-up from sleep costs tens of microseconds.
    for (int spin = 0; spin < 20000 && generation_.load(std::memory_order_acquire) == seen; ++spin)
      relax();
    generation_.wait(seen, std::memory_order_acquire);
    seen = generation_.load(std::memory_order_acquire);
    if (stop_.load(std::memory_order_acquire)) return;
    (*job_)(member);
    pending_.fetch_sub(1, std::memory_order_release);
  }
}

}  // namespace bisturi::sim
