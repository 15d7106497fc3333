#include "command_slew.h"

#include <algorithm>
#include <cmath>

namespace bisturi::runtime {

namespace {

double magnitude(const double* v, std::size_t n) {
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    sum += v[i] * v[i];
  return std::sqrt(sum);
}

}  // namespace

CommandSlew::CommandSlew(const std::vector<devices::ForceChannel>& channels, double period_s) {
  std::size_t offset = 0;
  for (const devices::ForceChannel& c : channels) {
    channels_.push_back({offset, c.components, c.max_force_rate_N_per_s * period_s});
    offset += c.components;
  }
  last_.assign(offset, 0.0);
}

bool CommandSlew::apply(std::span<double> command) noexcept {
  bool limited = false;
  for (const Channel& c : channels_) {
    if (c.offset + c.components > command.size()) break;
    double* now = command.data() + c.offset;
    double* last = last_.data() + c.offset;
    if (c.components == 1) {
      const double held = std::clamp(now[0], last[0] - c.step_N, last[0] + c.step_N);
      limited = limited || held != now[0];
      now[0] = held;
    } else {
      const double want = magnitude(now, c.components);
      const double was = magnitude(last, c.components);
      if (want > 0.0) {
        const double held = std::clamp(want, was - c.step_N, was + c.step_N);
        if (held != want) {
          limited = true;
          for (std::size_t i = 0; i < c.components; ++i)
            now[i] *= held / want;
        }
      }
    }
    std::copy(now, now + c.components, last);
  }
  return limited;
}

void CommandSlew::reset() noexcept {
  std::fill(last_.begin(), last_.end(), 0.0);
}

}  // namespace bisturi::runtime
