// Multi-rate lockstep of haptic ticks and tissue steps (see step_schedule.h).

#include "step_schedule.h"

#include <algorithm>

namespace bisturi::runtime {

StepSchedule::StepSchedule(std::uint32_t base_lag, std::uint32_t ticks_per_step)
    : base_lag_(base_lag),
      n_(std::max(1u, ticks_per_step)),
      next_hand_over_(n_),
      // A step comes due base_lag + n - 1 ticks after its hand-over, and hand-overs are at least
      // a tick apart: with due() asked every tick no more than base_lag + 1 wait at once.
      due_ticks_(base_lag + 2, 0) {}

bool StepSchedule::hands_over(std::uint64_t k) {
  if (k != next_hand_over_) return false;
  handed_over_ticks_ = n_;
  ++steps_;
  if (pending_ == due_ticks_.size()) {  // due() not asked every tick: make room (allocates)
    std::rotate(due_ticks_.begin(), due_ticks_.begin() + static_cast<std::ptrdiff_t>(head_),
                due_ticks_.end());
    head_ = 0;
    due_ticks_.resize(2 * due_ticks_.size());
  }
  due_ticks_[(head_ + pending_) % due_ticks_.size()] = k + base_lag_ + n_ - 1;
  ++pending_;
  next_hand_over_ = k + n_;
  return true;
}

void StepSchedule::forget_hand_over() {
  if (pending_ == 0) return;
  --pending_;
  --steps_;
}

void StepSchedule::set_ticks_per_step(std::uint64_t k, std::uint32_t n) {
  n_ = std::max(1u, n);
  next_hand_over_ = k + n_;
}

std::uint64_t StepSchedule::due(std::uint64_t k) {
  while (pending_ > 0 && due_ticks_[head_] <= k) {
    head_ = (head_ + 1) % due_ticks_.size();
    --pending_;
    ++due_;
  }
  return due_;
}

std::uint32_t ticks_per_step_for(double step_ms, double haptic_period_ms, double max_load,
                                 std::uint32_t max_ticks) {
  std::uint32_t n = 1;
  while (n < max_ticks && step_too_slow(step_ms, n, haptic_period_ms, max_load))
    n *= 2;
  return std::min(n, std::max(1u, max_ticks));
}

TissueRateController::TissueRateController(std::uint32_t ticks_per_step, std::uint32_t max_ticks,
                                           double haptic_period_ms, double max_load)
    : n_(std::max(1u, ticks_per_step)),
      max_(std::max(n_, max_ticks)),
      period_ms_(haptic_period_ms),
      max_load_(max_load) {}

std::uint32_t TissueRateController::decide(double median_step_ms, bool cutting) {
  ++since_change_;
  constexpr std::uint32_t kWhileCutting = 2;
  if (cutting && n_ < kWhileCutting && max_ >= kWhileCutting) {
    n_ = kWhileCutting;
    since_change_ = 0;
    return n_;
  }
  // 48 steps after a change the median (of 32, TissueThread::median_step_ms) holds steps of the
  // new length only. Going down waits longer: a step that just fits is worse than a longer one.
  const double covered_ms = n_ * period_ms_;
  if (since_change_ >= 48 && step_too_slow(median_step_ms, n_, period_ms_, max_load_) &&
      n_ < max_) {
    n_ = std::min(max_, 2 * n_);
    since_change_ = 0;
  } else if (since_change_ >= 256 && n_ > (cutting ? kWhileCutting : 1) &&
             median_step_ms < 0.75 * max_load_ * (covered_ms / 2)) {
    // Back up when the step fits the shorter time with a quarter of its share to spare: a step
    // that only just fitted stayed at the lower rate for good after one busy moment (a cut, the
    // renderer's burst), and a shorter step is no dearer (the solve converges sooner).
    n_ /= 2;
    since_change_ = 0;
  }
  return n_;
}

}  // namespace bisturi::runtime
