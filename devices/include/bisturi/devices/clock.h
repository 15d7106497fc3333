// One injectable monotonic clock for live sessions (SteadyClock) and replay (VirtualClock), so a
// replayed trace gives the same forces as the recorded session.
#pragma once

#include <atomic>
#include <chrono>

namespace bisturi::devices {

using Nanoseconds = std::chrono::nanoseconds;

class Clock {
 public:
  virtual ~Clock();
  // Monotonic time in nanoseconds since an arbitrary epoch.
  virtual Nanoseconds now() const = 0;
  // Blocks until now() >= t (SteadyClock) or moves time to t (VirtualClock, never backwards).
  virtual void sleep_until(Nanoseconds t) = 0;
};

// std::chrono::steady_clock.
class SteadyClock final : public Clock {
 public:
  Nanoseconds now() const override;
  void sleep_until(Nanoseconds t) override;
};

// Time that moves only when told to. Thread-safe.
class VirtualClock final : public Clock {
 public:
  explicit VirtualClock(Nanoseconds start = Nanoseconds{0}) : now_ns_(start.count()) {}
  Nanoseconds now() const override { return Nanoseconds{now_ns_.load()}; }
  void sleep_until(Nanoseconds t) override;
  void advance(Nanoseconds dt) { now_ns_.fetch_add(dt.count()); }
  void set(Nanoseconds t) { now_ns_.store(t.count()); }

 private:
  std::atomic<Nanoseconds::rep> now_ns_;
};

// A process-wide SteadyClock for callers that do not inject one.
Clock& steady_clock();

}  // namespace bisturi::devices
