#pragma once
// The live session's haptic thread: paces the ticks of the haptic loop (haptic_loop.h) at the
// scene's rate (sleep, then spin to the deadline), measures periods, overruns and missed
// deadlines into the report, samples the force for its plot, and ends with the loop's stop():
// zero out before anything else of the session winds down.

#include <atomic>
#include <cstdint>

#include "bisturi/devices/clock.h"
#include "bisturi/runtime/session/session.h"
#include "haptic_loop.h"

namespace bisturi::runtime {

struct HapticPacing {
  devices::Nanoseconds period{1'000'000};
  /// Sleep until this long before each deadline, then spin (0: sleep only). Adaptive: at most
  /// this long, as long as the wakeups need (wakeup_spin.h).
  devices::Nanoseconds spin{0};
  bool adaptive_spin = false;
  /// The session ends at this session time.
  devices::Nanoseconds duration{0};
  bool realtime_priority = false;
  /// Set from outside (SIGINT, SIGTERM) to end early; null: never.
  const std::atomic<bool>* stop_requested = nullptr;
};

/// What the haptic thread shares with the session's other threads.
struct HapticThreadFlags {
  std::atomic<bool>& stop;         ///< read: end now; set when the thread ends
  const std::atomic<bool>& ready;  ///< the ticks start once the renderer is up
  std::atomic<bool>& interrupted;  ///< set when stop_requested ended it
  std::atomic<bool>& realtime;     ///< set when SCHED_FIFO was granted
  std::atomic<std::uint64_t>& ticks;
  std::atomic<std::uint64_t>& overruns;
  std::atomic<double>& force_now;  ///< the proxy force now, for the progress line
  /// An injected fault's watch: while fault_at_ns >= 0 (clock time of the fault) and
  /// zero_at_ns < 0, the first tick after it whose output is zero on every channel sets
  /// zero_at_ns. output_now_N: the largest force on a channel at the last tick.
  std::atomic<std::int64_t>* fault_at_ns = nullptr;
  std::atomic<std::int64_t>* zero_at_ns = nullptr;
  std::atomic<double>* output_now_N = nullptr;
};

/// Runs the ticks until the duration, `flags.stop` or stop_requested, then stops the loop (zero
/// out) and sets flags.stop. `t0` gets the clock time of the session's start. Never throws.
void run_haptic_thread(HapticLoop& loop, devices::Clock& clock, const HapticPacing& pacing,
                       HapticThreadFlags& flags, SessionReport& report,
                       devices::Nanoseconds& t0) noexcept;

}  // namespace bisturi::runtime
