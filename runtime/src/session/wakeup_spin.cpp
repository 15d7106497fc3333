// The haptic thread's spin before each deadline, from how late its wakeups come (see
// wakeup_spin.h).

#include "wakeup_spin.h"

#include <algorithm>

namespace bisturi::runtime {

using devices::Nanoseconds;

WakeupSpin::WakeupSpin(const Limits& limits) : limits_(limits), spin_(limits.ceiling) {
  limits_.floor = std::min(limits_.floor, limits_.ceiling);
}

Nanoseconds WakeupSpin::clamped(Nanoseconds spin) const noexcept {
  return std::clamp(spin, limits_.floor, limits_.ceiling);
}

void WakeupSpin::woke(Nanoseconds late) noexcept {
  late = std::max(late, Nanoseconds{0});
  late_ns_[wakeups_ % kWindow] = late.count();
  ++wakeups_;
  // Late past the spin: the tick started late, or nearly. Cover it from the next tick on.
  if (late + limits_.margin > spin_) spin_ = clamped(late + limits_.margin);
  if (wakeups_ % kEvery == 0) take_percentile();
}

std::optional<Nanoseconds> sleep_then_spin(devices::Clock& clock, Nanoseconds deadline,
                                           Nanoseconds spin) {
  const Nanoseconds wake_at = deadline - spin;
  const bool sleeps = clock.now() < wake_at;
  clock.sleep_until(wake_at);
  std::optional<Nanoseconds> late;
  if (sleeps) late = clock.now() - wake_at;
  while (clock.now() < deadline) {
  }
  return late;
}

void WakeupSpin::take_percentile() noexcept {
  const auto n = static_cast<std::ptrdiff_t>(std::min<std::uint64_t>(wakeups_, kWindow));
  std::copy_n(late_ns_.begin(), n, scratch_.begin());
  const std::ptrdiff_t k = 99 * (n - 1) / 100;
  std::nth_element(scratch_.begin(), scratch_.begin() + k, scratch_.begin() + n);
  spin_ = clamped(Nanoseconds{scratch_[static_cast<std::size_t>(k)]} + limits_.margin);
}

}  // namespace bisturi::runtime
