#include "bisturi/devices/force_guard.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

namespace bisturi::devices {

const char* to_string(GuardState state) {
  switch (state) {
    case GuardState::WaitingForSmallCommand:
      return "waiting-for-small-command";
    case GuardState::RampingIn:
      return "ramping-in";
    case GuardState::Engaged:
      return "engaged";
    case GuardState::Latched:
      return "latched";
  }
  return "unknown";
}

const char* to_string(Fault fault) {
  switch (fault) {
    case Fault::None:
      return "none";
    case Fault::ForceAboveLimit:
      return "force-above-limit";
    case Fault::ForceRateAboveLimit:
      return "force-rate-above-limit";
    case Fault::NonFiniteCommand:
      return "non-finite-command";
    case Fault::DeadlineOverrun:
      return "deadline-overrun";
    case Fault::DeviceSilent:
      return "device-silent";
    case Fault::DeviceDisconnected:
      return "device-disconnected";
    case Fault::MalformedReport:
      return "malformed-report";
  }
  return "unknown";
}

namespace {

bool is_watchdog_fault(Fault fault) {
  return fault == Fault::DeadlineOverrun || fault == Fault::DeviceSilent;
}

double norm(const double* v, std::size_t n) {
  double sum = 0;
  for (std::size_t i = 0; i < n; ++i)
    sum += v[i] * v[i];
  return std::sqrt(sum);
}

}  // namespace

ForceGuard::ForceGuard(std::vector<ForceChannel> channels, ForceGuardConfig config)
    : channels_(std::move(channels)), config_(config) {
  std::size_t components = 0;
  for (const auto& channel : channels_) {
    if (!(channel.max_force_N > 0) || !std::isfinite(channel.max_force_N) ||
        !(channel.max_force_rate_N_per_s > 0) || !std::isfinite(channel.max_force_rate_N_per_s)) {
      throw std::invalid_argument("force guard: channel '" + channel.name +
                                  "' needs positive, finite max_force_N and "
                                  "max_force_rate_N_per_s");
    }
    if (channel.components != 1 && channel.components != 3) {
      throw std::invalid_argument("force guard: channel '" + channel.name +
                                  "' must have 1 or 3 components");
    }
    components += channel.components;
  }
  if (config_.period.count() <= 0 || config_.deadline_margin.count() < 0 ||
      config_.device_silence_timeout.count() <= 0 || config_.ramp_in.count() < 0 ||
      !(config_.engage_threshold_N > 0)) {
    throw std::invalid_argument("force guard: invalid configuration");
  }
  output_.assign(components, 0.0);
  scratch_.assign(components, 0.0);
}

void ForceGuard::latch(Fault reason) {
  state_ = GuardState::Latched;
  latch_reason_ = reason;
  std::fill(output_.begin(), output_.end(), 0.0);
}

Fault ForceGuard::watchdog_fault(Nanoseconds now) const {
  if (have_step_ && now - last_step_ > config_.period + config_.deadline_margin) {
    return Fault::DeadlineOverrun;
  }
  if (have_answer_ && now - last_answer_ > config_.device_silence_timeout) {
    return Fault::DeviceSilent;
  }
  return Fault::None;
}

void ForceGuard::device_answered(Nanoseconds t) {
  if (!have_answer_ || t > last_answer_) last_answer_ = t;
  have_answer_ = true;
}

void ForceGuard::device_disconnected() {
  latch(Fault::DeviceDisconnected);
}

bool ForceGuard::watchdog_expired(Nanoseconds now) {
  const Fault fault = watchdog_fault(now);
  if (fault == Fault::None) return false;
  if (state_ != GuardState::Latched) latch(fault);
  return true;
}

void ForceGuard::deadline_missed() {
  if (state_ != GuardState::Latched) latch(Fault::DeadlineOverrun);
}

void ForceGuard::rearm() {
  state_ = GuardState::WaitingForSmallCommand;
  latch_reason_ = Fault::None;
  std::fill(output_.begin(), output_.end(), 0.0);
  have_step_ = false;
  have_answer_ = false;
}

GuardStep ForceGuard::step(std::span<const double> command_N, Nanoseconds now,
                           std::span<double> out_N) {
  if (command_N.size() != output_.size() || out_N.size() != output_.size()) {
    throw std::invalid_argument("force guard: expected " + std::to_string(output_.size()) +
                                " force components, got " + std::to_string(command_N.size()) +
                                " in and " + std::to_string(out_N.size()) + " out");
  }
  GuardStep result;
  // The silence watchdog starts with the first step when the device has not answered yet.
  if (!have_answer_) {
    have_answer_ = true;
    last_answer_ = now;
  }
  const Fault watchdog = watchdog_fault(now);
  const Nanoseconds dt = have_step_ ? now - last_step_ : config_.period;
  have_step_ = true;
  last_step_ = now;

  if (state_ == GuardState::Latched && config_.watchdog_auto_rearm &&
      is_watchdog_fault(latch_reason_) && watchdog == Fault::None) {
    state_ = GuardState::WaitingForSmallCommand;
    latch_reason_ = Fault::None;
  }
  if (state_ != GuardState::Latched && watchdog != Fault::None) {
    latch(watchdog);
    result.latched = watchdog;
  }
  if (state_ != GuardState::Latched) {
    for (double value : command_N) {
      if (!std::isfinite(value)) {
        latch(Fault::NonFiniteCommand);
        result.latched = Fault::NonFiniteCommand;
        break;
      }
    }
  }
  if (state_ == GuardState::Latched) {
    result.state = state_;
    std::fill(out_N.begin(), out_N.end(), 0.0);
    return result;
  }

  // Clamp each channel's magnitude to its limit.
  bool all_small = true;
  std::size_t offset = 0;
  for (const auto& channel : channels_) {
    const std::size_t n = channel.components;
    const double magnitude = force_extent(channel, command_N.data() + offset);
    const double scale = magnitude > channel.max_force_N ? channel.max_force_N / magnitude : 1.0;
    // At the limit counts too: a command clamped upstream arrives exactly there.
    if (magnitude >= channel.max_force_N) result.clamped = true;
    if (magnitude >= config_.engage_threshold_N) all_small = false;
    for (std::size_t i = 0; i < n; ++i)
      scratch_[offset + i] = command_N[offset + i] * scale;
    offset += n;
  }
  if (result.clamped) ++clamps_;

  // Engage once the command is small, then ramp in.
  if (state_ == GuardState::WaitingForSmallCommand && all_small) {
    state_ = GuardState::RampingIn;
    ramp_start_ = now;
  }
  double gain = 1.0;
  if (state_ == GuardState::WaitingForSmallCommand) {
    gain = 0.0;
  } else if (state_ == GuardState::RampingIn) {
    const auto elapsed = now - ramp_start_;
    if (config_.ramp_in.count() == 0 || elapsed >= config_.ramp_in) {
      state_ = GuardState::Engaged;
    } else {
      gain = static_cast<double>(elapsed.count()) / static_cast<double>(config_.ramp_in.count());
    }
  }

  // Limit how fast each channel's force may change.
  const double dt_s =
      std::clamp(std::chrono::duration<double>(dt).count(), 0.0,
                 std::chrono::duration<double>(config_.period + config_.deadline_margin).count());
  offset = 0;
  for (const auto& channel : channels_) {
    const std::size_t n = channel.components;
    double delta[3];
    for (std::size_t i = 0; i < n; ++i) {
      delta[i] = gain * scratch_[offset + i] - output_[offset + i];
    }
    const double change = norm(delta, n);
    const double allowed = channel.max_force_rate_N_per_s * dt_s;
    const double scale = change > allowed ? allowed / change : 1.0;
    if (scale < 1.0) result.rate_limited = true;
    for (std::size_t i = 0; i < n; ++i)
      output_[offset + i] += delta[i] * scale;
    offset += n;
  }
  if (result.rate_limited) ++rate_limits_;
  std::copy(output_.begin(), output_.end(), out_N.begin());
  result.state = state_;
  return result;
}

}  // namespace bisturi::devices
