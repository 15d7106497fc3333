#pragma once
// Seconds on the steady clock since a start: the extractions' stage timings.

#include <chrono>

namespace bisturi::surface {

inline double seconds_since(std::chrono::steady_clock::time_point start) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

}  // namespace bisturi::surface
