#pragma once
// Multi-rate lockstep between the 1 kHz haptic ticks and the soft-tissue steps. A step covers
// `ticks_per_step` ticks (its time step is that many haptic periods) and runs on the haptic state
// of its last tick, the hand-over tick. A step handed over at tick p with n ticks per step is due
// at tick p + base_lag + n - 1: a longer step gets as much more time as it covers. With one tick
// per step this is the plain lockstep (tick k sends step k - base_lag).
//
// The number of ticks per step may change at a hand-over tick (the live session adapts it to how
// long steps take on the machine, and writes each change into its trace); the schedule is then
// fixed by the ticks and the recorded changes alone, so a replay in virtual time pairs the same
// steps with the same ticks.

#include <cstdint>
#include <vector>

namespace bisturi::runtime {

/// The step whose command tick k sends when it is on time in the plain lockstep: k - lag (0,
/// none, for the first ticks).
constexpr std::uint64_t scheduled_step(std::uint64_t k, std::uint32_t lag) {
  return k > lag ? k - lag : 0;
}

class StepSchedule {
 public:
  StepSchedule(std::uint32_t base_lag, std::uint32_t ticks_per_step);

  /// Tick k (1-based; call once per tick, in order): true when it hands its haptic state over as
  /// the next step, whose length (ticks) is then handed_over_ticks().
  bool hands_over(std::uint64_t k);
  [[nodiscard]] std::uint32_t handed_over_ticks() const { return handed_over_ticks_; }
  /// The step handed over at this tick was not taken (the tissue's queue was full): it never
  /// becomes due, and the next hand-over takes its number. The hand-over ticks stay as they were.
  void forget_hand_over();
  /// At hand-over tick k: the steps after this one cover n ticks each (n >= 1).
  void set_ticks_per_step(std::uint64_t k, std::uint32_t n);
  [[nodiscard]] std::uint32_t ticks_per_step() const { return n_; }
  /// The step whose command tick k sends when the tissue is on time: the newest one due at k
  /// (0 before the first). k must not decrease between calls.
  std::uint64_t due(std::uint64_t k);
  /// Steps handed over so far.
  [[nodiscard]] std::uint64_t steps() const { return steps_; }

 private:
  std::uint32_t base_lag_;
  std::uint32_t n_;
  std::uint32_t handed_over_ticks_ = 0;
  std::uint64_t next_hand_over_;
  std::uint64_t steps_ = 0;
  std::uint64_t due_ = 0;
  /// Ring of the due ticks of the steps handed over and not yet due (a tick never allocates).
  std::vector<std::uint64_t> due_ticks_;
  std::size_t head_ = 0, pending_ = 0;
};

/// Whether a step of step_ms takes more than max_load of the `ticks` haptic periods it covers:
/// the controller's criterion for doubling the ticks per step.
constexpr bool step_too_slow(double step_ms, std::uint32_t ticks, double haptic_period_ms,
                             double max_load) {
  return step_ms > max_load * (ticks * haptic_period_ms);
}

/// The fewest ticks per step (a power of two, at most max_ticks) for which a step of step_ms is
/// not too slow (step_too_slow), to pick the first rate (rate_calibration.h).
std::uint32_t ticks_per_step_for(double step_ms, double haptic_period_ms, double max_load,
                                 std::uint32_t max_ticks);

/// Picks the ticks per step from how long the tissue thread's steps take: doubles it (up to
/// max_ticks) when the median step takes more than `max_load` (3/4) of the time it covers,
/// halves it when the median would take under three quarters of that share of the halved
/// step's time, with
/// a pause after each change so the median (of the last 32 steps) can follow. While a blade
/// sweeps through tissue it keeps at least two ticks per step: the cut it makes at the sweep's
/// end is one long step (the volume's separation), and steps of one tick catch up from it so
/// slowly that the force faded on a stale step for 12-20 ticks.
class TissueRateController {
 public:
  TissueRateController(std::uint32_t ticks_per_step, std::uint32_t max_ticks,
                       double haptic_period_ms, double max_load = 0.75);
  /// At a hand-over: the median wall time of the recent steps and whether a blade is sweeping
  /// (the newest step's); returns the ticks per step to use from the next step on.
  std::uint32_t decide(double median_step_ms, bool cutting = false);

 private:
  std::uint32_t n_;
  std::uint32_t max_;
  double period_ms_;
  double max_load_;
  std::uint64_t since_change_ = 0;
};

}  // namespace bisturi::runtime
