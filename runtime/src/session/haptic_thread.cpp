// The live session's haptic thread (see haptic_thread.h).

#include "haptic_thread.h"

#include "wakeup_spin.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <optional>
#include <thread>

#include <glm/geometric.hpp>

namespace bisturi::runtime {

namespace {

using devices::Nanoseconds;

double ms(Nanoseconds d) {
  return static_cast<double>(d.count()) * 1e-6;
}

/// The output's largest channel, and an injected fault's first all-zero tick after it. A lost
/// device is sent nothing: its output is zero from the tick that found it gone.
void watch_fault(const HapticLoop& loop, Nanoseconds now, HapticThreadFlags& flags) {
  const double largest = loop.device_lost() ? 0.0 : loop.largest_output_N();
  flags.output_now_N->store(largest, std::memory_order_relaxed);
  const std::int64_t fault = flags.fault_at_ns->load(std::memory_order_acquire);
  if (fault >= 0 && largest == 0.0 && now.count() >= fault) {
    std::int64_t none = -1;  // the supervisor may have seen the zero first
    flags.zero_at_ns->compare_exchange_strong(none, now.count(), std::memory_order_acq_rel);
  }
}

}  // namespace

void run_haptic_thread(HapticLoop& loop, devices::Clock& clock, const HapticPacing& pacing,
                       HapticThreadFlags& flags, SessionReport& report, Nanoseconds& t0) noexcept {
  if (pacing.realtime_priority) flags.realtime.store(request_realtime_priority(0));
  while (!flags.ready.load())
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  const Nanoseconds period = pacing.period;
  // The force plot samples at 200 Hz (its buffer was reserved before the session started).
  const std::uint64_t force_every = std::max<std::uint64_t>(
      1, static_cast<std::uint64_t>(std::llround(5e6 / static_cast<double>(period.count()))));
  t0 = clock.now();
  Nanoseconds next = t0;
  Nanoseconds previous_start{0};
  bool first = true;
  WakeupSpin wakeup(WakeupSpin::Limits{.ceiling = pacing.spin});
  while (!flags.stop.load(std::memory_order_relaxed)) {
    if (pacing.stop_requested != nullptr && pacing.stop_requested->load()) {
      flags.interrupted.store(true);
      break;
    }
    const Nanoseconds spin = pacing.adaptive_spin ? wakeup.spin() : pacing.spin;
    const std::optional<Nanoseconds> late = sleep_then_spin(clock, next, spin);
    if (spin.count() > 0) {
      if (late) {
        wakeup.woke(*late);
        report.haptic_wake_late_us.record(static_cast<double>(late->count()) * 1e-3);
      }
      report.haptic_spin_us.record(static_cast<double>(spin.count()) * 1e-3);
    }
    const Nanoseconds start = clock.now();
    const Nanoseconds t = start - t0;
    if (t >= pacing.duration) break;
    if (!first) {
      const double p_ms = ms(start - previous_start);
      report.haptic_period_ms.record(p_ms);
      report.haptic_period_error_ms.record(std::abs(p_ms - ms(period)));
    }
    first = false;
    previous_start = start;

    (void)loop.tick(t);
    const std::uint64_t k = loop.counters().ticks;
    const TickOutput* out = loop.step_output();
    const double proxy_N = out != nullptr ? glm::length(out->force_N) : 0.0;
    if (k % force_every == 0 && report.force.size() < report.force.capacity()) {
      const std::vector<double>& command = loop.command();
      report.force.push_back(
          {ms(t) * 1e-3, proxy_N, command.empty() ? 0.0 : command[0], loop.first_output_N()});
    }
    flags.force_now.store(proxy_N, std::memory_order_relaxed);
    if (flags.output_now_N != nullptr) watch_fault(loop, clock.now(), flags);

    const Nanoseconds end = clock.now();
    report.tick_ms.record(ms(end - start));
    if (end - start > period) flags.overruns.fetch_add(1, std::memory_order_relaxed);
    next += period;
    if (end > next) {
      ++report.missed_deadlines;
      // Kept up to the room reserved before the session: nothing is allocated here.
      if (report.missed_deadline_ticks.size() < report.missed_deadline_ticks.capacity())
        report.missed_deadline_ticks.push_back(k);
      // The tick's own work took under half a period: the thread was started late (the OS, or
      // on a virtual machine the hypervisor, had the core), not slowed by its work.
      if (end - start < period / 2) ++report.missed_by_late_wakeup;
    }
    if (end > next + period) {  // fell behind by more than a period: drop those ticks
      const std::int64_t behind = (end - next).count() / period.count();
      report.skipped_ticks += static_cast<std::uint64_t>(behind);
      next += period * behind;
    }
    flags.ticks.store(k, std::memory_order_relaxed);
  }
  // Zero first: before the tissue drains and the renderer joins.
  loop.stop();
  if (flags.output_now_N != nullptr) watch_fault(loop, clock.now(), flags);
  flags.stop.store(true);
}

}  // namespace bisturi::runtime
