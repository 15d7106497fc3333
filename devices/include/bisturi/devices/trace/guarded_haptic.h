#pragma once
// The haptic loop's per-device steps as traces record and replay them. A live session and
// replay_trace() both go through these, so a replayed trace meets the force guard with the same
// commands at the same times and the driver writes the same bytes:
//   poll:  device.poll(); the guard hears that the device answered at the last report's time;
//   send:  the command is filtered by the guard at clock.now(), the guarded forces go to the
//          driver, and then the command is recorded (kForceCommand, N per actuator, at that
//          same time): the trace never stands between a force and the device;
//   lost:  DeviceDisconnected latches the guard to zero;
//   back:  a reconnected device gets a new driver (open_recorded with its index) and guard.rearm();
//   end:   the devices are closed (their zero-force reports are recorded), then the writer.

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/trace_writer.h"

namespace bisturi::devices {

/// A driver opened on a recorded transport, and its device index in the trace.
struct RecordedDevice {
  std::unique_ptr<Device> device;
  std::uint16_t index = 0;
};

/// Opens the driver that `registry` picks for `transport`, with everything crossing the transport
/// recorded into `writer`. Without `index` the device is added to the trace (kDeviceAdded, its
/// description naming the driver) and gets the next index; a reconnecting device passes the index
/// it had. The writer and the clock must outlive the device. Throws DeviceError when no driver
/// fits, TraceError when the trace cannot be written.
RecordedDevice open_recorded(const Registry& registry, std::unique_ptr<Transport> transport,
                             TraceWriter& writer, Clock& clock,
                             std::optional<std::uint16_t> index = std::nullopt);

/// The force guard's settings as the JSON object a trace's configuration holds under
/// "force_guard" (times in nanoseconds): `{"force_guard": {...}}`.
std::string force_guard_config_json(const ForceGuardConfig& config);
/// The "force_guard" object of a trace configuration; `fallback` where the configuration has none
/// (or is not JSON). Throws TraceError on a "force_guard" object with a field of the wrong type.
ForceGuardConfig force_guard_config_from_json(std::string_view config,
                                              const ForceGuardConfig& fallback = {});

/// One haptic device with its force guard (see the top of this file).
class GuardedHaptic {
 public:
  /// `device`, `guard` and `clock` are observed; with a `writer`, force commands are recorded as
  /// device `index`.
  GuardedHaptic(HapticDevice& device, ForceGuard& guard, Clock& clock,
                TraceWriter* writer = nullptr, std::uint16_t index = 0);

  /// device.poll(timeout); when reports were handled the guard hears that the device answered:
  /// recording, at the time the last report was recorded (as a replay's guard hears it), else at
  /// state().sample_time. DeviceDisconnected latches the guard and is rethrown; ProtocolError (a
  /// malformed report, dropped) propagates with the guard untouched.
  std::size_t poll(std::chrono::microseconds timeout);
  /// Filters `command_N` through the guard at clock.now(), sends the result, then records the
  /// command. DeviceDisconnected latches the guard and is rethrown (the command recorded first).
  GuardStep send(std::span<const double> command_N);

  HapticDevice& device() { return *device_; }
  ForceGuard& guard() { return *guard_; }
  /// What the last send() gave the driver.
  const std::vector<double>& last_output_N() const { return output_; }

 private:
  void record(Nanoseconds time, std::span<const double> command_N);
  HapticDevice* device_;
  ForceGuard* guard_;
  Clock* clock_;
  TraceWriter* writer_;
  std::uint16_t index_;
  std::vector<double> output_;
};

}  // namespace bisturi::devices
