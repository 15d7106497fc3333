#include "bisturi/devices/clock.h"

#include <thread>

namespace bisturi::devices {

Clock::~Clock() = default;

Nanoseconds SteadyClock::now() const {
  return std::chrono::duration_cast<Nanoseconds>(
      std::chrono::steady_clock::now().time_since_epoch());
}

void SteadyClock::sleep_until(Nanoseconds t) {
  std::this_thread::sleep_until(std::chrono::steady_clock::time_point(
      std::chrono::duration_cast<std::chrono::steady_clock::duration>(t)));
}

void VirtualClock::sleep_until(Nanoseconds t) {
  auto current = now_ns_.load();
  while (current < t.count() && !now_ns_.compare_exchange_weak(current, t.count())) {
  }
}

Clock& steady_clock() {
  static SteadyClock clock;
  return clock;
}

}  // namespace bisturi::devices
