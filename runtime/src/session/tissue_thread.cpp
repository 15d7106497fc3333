// The soft-tissue step on its own thread (see tissue_thread.h).

#include "tissue_thread.h"

#include "bisturi/runtime/heap_policy.h"

#include <pthread.h>
#include <sched.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <stdexcept>
#include <string>

namespace bisturi::runtime {

namespace {

/// The median of the first `count` values (all of them once there are as many).
template <std::size_t N>
double median_of_first(std::array<double, N> values, std::uint64_t count) {
  const auto n = static_cast<std::size_t>(std::min<std::uint64_t>(count, N));
  std::nth_element(values.begin(), values.begin() + n / 2, values.begin() + n);
  return values[n / 2];
}
/// What the tissue thread faults in as it starts: a few times what the default scene's cut
/// allocates (some 460 pages).
constexpr std::size_t kPrefaultBytes = std::size_t{16} << 20;
}  // namespace

TissueThread::TissueThread(SessionSim& sim, std::vector<devices::HapticState> shapes, bool threaded,
                           bool realtime_priority, AfterStep after_step, std::size_t capacity)
    : sim_(sim),
      after_step_(std::move(after_step)),
      capacity_(capacity),
      states_(capacity, shapes),
      ticks_(capacity, 1),
      blood_held_(capacity, 0),
      outputs_(capacity) {
  // No allocation when a step's output is copied.
  for (TickOutput& o : outputs_) {
    o.other_hands.resize(sim.hand_count() - 1);
    for (std::size_t h = 0; h < sim.hand_count(); ++h)
      o.hand(h).command_N.reserve(sim.command_size(h));
  }
  if (!threaded) return;
  thread_ = std::thread([this, realtime_priority] {
    if (realtime_priority) (void)request_realtime_priority(1);  // under haptics, over render
    // A cut's step builds a new lattice and its matrix: its memory is faulted in now, before
    // the haptic clock starts, not while the force waits for that step.
    prefault_thread_heap(kPrefaultBytes);
    started_.store(true, std::memory_order_release);
    started_.notify_one();
    run();
  });
  started_.wait(false, std::memory_order_acquire);
}

TissueThread::~TissueThread() {
  stop_thread();
}

void TissueThread::stop_thread() {
  if (!thread_.joinable()) return;
  finishing_.store(true, std::memory_order_release);
  wake_.fetch_add(1, std::memory_order_release);
  wake_.notify_one();
  thread_.join();
}

bool request_realtime_priority(int below) {
  sched_param p{};
  p.sched_priority = std::max(1, sched_get_priority_max(SCHED_FIFO) / 2 - below);
  return pthread_setschedparam(pthread_self(), SCHED_FIFO, &p) == 0;
}

TissueThread::Push TissueThread::push(std::span<const devices::HapticState> states,
                                      std::uint32_t ticks, bool blood_held) {
  if (failed_.load(std::memory_order_acquire)) return Push::Failed;
  const std::uint64_t k = pushed_.load(std::memory_order_relaxed) + 1;
  if (k - done_.load(std::memory_order_acquire) >= capacity_) return Push::Behind;
  std::vector<devices::HapticState>& slot = states_[k % capacity_];
  for (std::size_t h = 0; h < std::min(slot.size(), states.size()); ++h)
    slot[h] = states[h];
  ticks_[k % capacity_] = ticks;
  blood_held_[k % capacity_] = blood_held ? 1 : 0;
  pushed_.store(k, std::memory_order_release);
  if (!thread_.joinable()) {
    try {
      step(k);
    } catch (...) {  // kept for finish(), which rethrows it outside the tick
      error_ = std::current_exception();
      failed_.store(true, std::memory_order_release);
      return Push::Failed;
    }
    return Push::Queued;
  }
  wake_.fetch_add(1, std::memory_order_release);
  wake_.notify_one();
  return Push::Queued;
}

const TickOutput* TissueThread::output(std::uint64_t j) const {
  if (j == 0 || j > done_.load(std::memory_order_acquire)) return nullptr;
  return &outputs_[j % capacity_];
}

TissueThread::TickStep TissueThread::step_for(std::uint64_t due) const {
  const std::uint64_t done = done_.load(std::memory_order_acquire);
  TickStep t;
  t.step = due;
  if (done < t.step) {
    t.step = done;
    t.late = true;
  }
  t.output = output(t.step);
  return t;
}

void TissueThread::step(std::uint64_t j) {
  const std::vector<devices::HapticState>& states = states_[j % capacity_];
  const std::uint32_t ticks = ticks_[j % capacity_];
  const auto begin = std::chrono::steady_clock::now();
  const TickOutput& out = sim_.tick(states, ticks, blood_held_[j % capacity_] != 0);
  const auto end = std::chrono::steady_clock::now();
  outputs_[j % capacity_] = out;
  if (after_step_)
    after_step_(out, states, std::chrono::duration<double, std::milli>(end - begin).count());
  done_.store(j, std::memory_order_release);
  // The rate controller reads the median of the recent steps' busy times: a cut's long step, or
  // a few steps the machine stole time from, do not move it. A step with an organ asleep counts
  // at least the median of the recent steps with every one awake: the organ wakes at its full
  // cost (a touch, another solid's push), so its sleep does not make the steps look cheaper
  // than they are with it awake.
  const double busy_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
  if (sim_.world().some_volume_asleep()) {
    recent_ms_[j % recent_ms_.size()] = std::max(busy_ms, awake_median_ms_);
  } else {
    recent_ms_[j % recent_ms_.size()] = busy_ms;
    awake_ms_[awake_steps_++ % awake_ms_.size()] = busy_ms;
    awake_median_ms_ = median_of_first(awake_ms_, awake_steps_);
  }
  median_step_ms_.store(median_of_first(recent_ms_, j), std::memory_order_relaxed);
}

void TissueThread::run() {
  try {
    std::uint64_t j = 0;
    for (;;) {
      const std::uint32_t seen = wake_.load(std::memory_order_acquire);
      if (j < pushed_.load(std::memory_order_acquire)) {
        step(++j);
        continue;
      }
      if (finishing_.load(std::memory_order_acquire)) break;
      wake_.wait(seen, std::memory_order_acquire);
    }
  } catch (...) {
    error_ = std::current_exception();
    failed_.store(true, std::memory_order_release);
  }
}

void TissueThread::finish() {
  stop_thread();
  if (error_) std::rethrow_exception(error_);
}

}  // namespace bisturi::runtime
