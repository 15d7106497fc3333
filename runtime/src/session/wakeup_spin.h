#pragma once
// How long the haptic thread spins before each deadline. It sleeps until the deadline less the
// spin and then spins, so the spin has to cover how late the OS wakes a sleeping thread; spun
// beyond that, it only takes a core the blood and the renderer could use (200 us before every
// tick of a 1 kHz loop is a fifth of a core). So the spin follows the wakeups: the 99th
// percentile of how late the last 512 came, plus a margin, kept between a floor and a ceiling
// (the session's spin_us). A wakeup later than the spin raises it at once; it comes down only
// as the window forgets.

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>

#include "bisturi/devices/clock.h"

namespace bisturi::runtime {

class WakeupSpin {
 public:
  struct Limits {
    devices::Nanoseconds floor{20'000};
    devices::Nanoseconds ceiling{200'000};  ///< also the spin until the first wakeups are in
    devices::Nanoseconds margin{10'000};    ///< above the percentile
  };
  /// How many wakeups the percentile is taken over, and how often it is taken again.
  static constexpr std::size_t kWindow = 512;
  static constexpr std::size_t kEvery = 128;

  explicit WakeupSpin(const Limits& limits);

  [[nodiscard]] devices::Nanoseconds spin() const { return spin_; }
  /// A sleep asked to end at some time and ended `late` after it. Neither allocates nor throws
  /// (the haptic thread calls it every tick).
  void woke(devices::Nanoseconds late) noexcept;

 private:
  [[nodiscard]] devices::Nanoseconds clamped(devices::Nanoseconds spin) const noexcept;
  void take_percentile() noexcept;

  Limits limits_;
  devices::Nanoseconds spin_;
  std::array<std::int64_t, kWindow> late_ns_{};  ///< ring of the latest wakeups
  std::array<std::int64_t, kWindow> scratch_{};  ///< reordered by the percentile's selection
  std::uint64_t wakeups_ = 0;
};

/// Sleeps until `spin` before `deadline`, then spins the rest of the way. Gives how late the
/// sleep ended, or nothing when the deadline less the spin had passed before it (no sleep: the
/// loop was behind, which says nothing of how late wakeups come).
std::optional<devices::Nanoseconds> sleep_then_spin(devices::Clock& clock,
                                                    devices::Nanoseconds deadline,
                                                    devices::Nanoseconds spin);

}  // namespace bisturi::runtime
