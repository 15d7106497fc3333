// The one safety stage every force passes through on its way to any driver:
//   command -> NaN/inf latch -> clamp to max_force_N -> engage/ramp-in gain -> rate limit -> device
// plus a watchdog (missed loop deadline, silent device) and a disconnect latch. All times come
// from the caller's Clock, so replay in virtual time gives the same forces.
#pragma once

#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"

namespace bisturi::devices {

struct ForceGuardConfig {
  // The loop's period and how late a step may come before the watchdog zeroes forces.
  Nanoseconds period{std::chrono::milliseconds(1)};
  Nanoseconds deadline_margin{std::chrono::milliseconds(2)};
  // The device "stops answering" when no input report came for this long.
  Nanoseconds device_silence_timeout{std::chrono::milliseconds(50)};
  // Forces engage only once every channel's command is below this magnitude...
  double engage_threshold_N = 0.1;
  // ...and then ramp in linearly from zero over this time.
  Nanoseconds ramp_in{std::chrono::milliseconds(250)};
  // After a watchdog latch (deadline, silence) the guard re-arms by itself once steps are on time
  // and the device answers again (then engage + ramp-in again). NaN and disconnect latches always
  // need rearm().
  bool watchdog_auto_rearm = true;
};

enum class GuardState : std::uint8_t {
  WaitingForSmallCommand,  // outputs zero until the command is small
  RampingIn,
  Engaged,
  Latched,  // outputs zero; see latch_reason()
};
const char* to_string(GuardState state);

// What went wrong, and how the session treats it.
enum class Fault : std::uint8_t {
  None,
  ForceAboveLimit,      // clamped, session goes on
  ForceRateAboveLimit,  // rate-limited, session goes on
  NonFiniteCommand,     // NaN or inf: latched zero
  DeadlineOverrun,      // loop late by more than the margin: latched zero
  DeviceSilent,         // no input report within the silence timeout: latched zero
  DeviceDisconnected,   // lost device: latched zero, its forces stop
  MalformedReport,      // a report was dropped, session goes on
};
const char* to_string(Fault fault);


struct GuardStep {
  GuardState state = GuardState::WaitingForSmallCommand;
  bool clamped = false;         // some channel was at or above max_force_N
  bool rate_limited = false;    // some channel changed faster than allowed
  Fault latched = Fault::None;  // set on the step that latched
};

class ForceGuard {
 public:
  // channels: the device's force channels (limits from its capabilities). Throws
  // std::invalid_argument on a channel with a non-positive or non-finite limit.
  explicit ForceGuard(std::vector<ForceChannel> channels, ForceGuardConfig config = {});

  // One haptic-loop step at time `now`: filters `command_N` (force_components() values, channel
  // after channel) into `out_N` (same length), which is what the driver may send. Throws
  // std::invalid_argument on wrong lengths.
  GuardStep step(std::span<const double> command_N, Nanoseconds now, std::span<double> out_N);

  // An input report arrived from the device at `t` (feeds the silence watchdog).
  void device_answered(Nanoseconds t);
  // The device is lost: latches zero at once. Send zeros (last_output()) before anything else.
  void device_disconnected();
  // Watchdog check without a command (e.g. from a supervisor thread): latches and returns true
  // when the loop missed its deadline or the device went silent.
  bool watchdog_expired(Nanoseconds now);

  // A supervisor saw the loop stall past its deadline (the haptic loop's zero_if_stalled):
  // latches zero at once, as a
  // missed deadline does (the output is zero immediately, not rate-limited down; it re-arms by
  // itself like a missed deadline when watchdog_auto_rearm).
  void deadline_missed();

  // Clears any latch; forces engage again once the command is small, then ramp in.
  void rearm();

  GuardState state() const { return state_; }
  Fault latch_reason() const { return latch_reason_; }
  const std::vector<double>& last_output() const { return output_; }
  const std::vector<ForceChannel>& channels() const { return channels_; }
  std::size_t force_components() const { return output_.size(); }
  const ForceGuardConfig& config() const { return config_; }
  // Counters since construction.
  std::uint64_t clamp_count() const { return clamps_; }
  std::uint64_t rate_limit_count() const { return rate_limits_; }

 private:
  void latch(Fault reason);
  Fault watchdog_fault(Nanoseconds now) const;

  std::vector<ForceChannel> channels_;
  ForceGuardConfig config_;
  GuardState state_ = GuardState::WaitingForSmallCommand;
  Fault latch_reason_ = Fault::None;
  std::vector<double> output_;
  std::vector<double> scratch_;
  bool have_step_ = false;
  Nanoseconds last_step_{0};
  bool have_answer_ = false;
  Nanoseconds last_answer_{0};
  Nanoseconds ramp_start_{0};
  std::uint64_t clamps_ = 0;
  std::uint64_t rate_limits_ = 0;
};

}  // namespace bisturi::devices
