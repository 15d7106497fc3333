#pragma once
// Wall time for the commands' progress lines and --json timings.

#include <chrono>

namespace bisturi::cli {

using Clock = std::chrono::steady_clock;

inline double milliseconds_since(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

}  // namespace bisturi::cli
