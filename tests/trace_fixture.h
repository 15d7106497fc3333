#pragma once
// Records a short haptic session with the simulated glove and head tracker into a trace, the way a
// live session does (RecordingTransport through open_recorded, forces through GuardedHaptic), in
// virtual time so the result is the same on every run. Used by trace_test and by
// make_trace_fixture, which wrote tests/data/traces/sim_glove.btrace.

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <memory>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/devices/virtual_transport.h"

namespace bisturi::devices::testing {

struct SimSessionOptions {
  std::chrono::milliseconds duration{200};
  /// The glove's report rate.
  double glove_rate_hz = 1000.0;
  /// How far the clock moves on each reading (0: only when the session sets it), as a live
  /// clock does between the transport's stamp and the driver's.
  Nanoseconds tick_per_reading{0};
  /// Unplug the glove at this time and plug it back 20 ms later (0: never).
  std::chrono::milliseconds unplug_at{0};
  bool tracker = true;
  TraceWriterOptions writer;
};

/// Virtual time that also moves by `tick` on every reading.
class TickingClock final : public Clock {
 public:
  TickingClock(Nanoseconds start, Nanoseconds tick) : now_ns_(start.count()), tick_(tick.count()) {}
  Nanoseconds now() const override { return Nanoseconds{now_ns_.fetch_add(tick_) + tick_}; }
  void sleep_until(Nanoseconds t) override {
    if (t > now()) set(t);
  }
  void set(Nanoseconds t) { now_ns_.store(t.count()); }

 private:
  mutable std::atomic<Nanoseconds::rep> now_ns_;
  Nanoseconds::rep tick_;
};

inline DeviceScript glove_script() {
  using std::chrono::milliseconds;
  DeviceScript s;
  MotionKey open;
  open.t = milliseconds(0);
  open.pose.position_m = {0.0, 0.1, 0.3};
  open.joints_rad.assign(SimulatedGlove::kJoints, 0.05);
  MotionKey grip = open;
  grip.t = milliseconds(150);
  grip.pose.position_m = {0.02, 0.12, 0.28};
  for (std::size_t j = 0; j < SimulatedGlove::kJoints; ++j) {
    grip.joints_rad[j] = 0.2 + 0.08 * static_cast<double>(j);
  }
  MotionKey release = open;
  release.t = milliseconds(300);
  s.motion = {open, grip, release};
  s.presses = {{milliseconds(40), 0, true}, {milliseconds(90), 0, false}};
  s.contacts = {{milliseconds(60), milliseconds(200), 4, 0.5}};
  return s;
}

inline DeviceScript head_script() {
  using std::chrono::milliseconds;
  DeviceScript s;
  MotionKey a;
  a.pose.position_m = {0.0, 1.6, 0.0};
  MotionKey b = a;
  b.t = milliseconds(300);
  b.pose.position_m = {0.05, 1.62, -0.02};
  b.pose.orientation = {0.9962, 0.0, 0.0872, 0.0};
  s.motion = {a, b};
  return s;
}

/// A spring on each finger (actuator i pulls back finger i's middle joint beyond 0.3 rad) and a
/// vibration while button 0 is held: an ordinary haptic-loop force, some of it above the limits.
inline std::vector<double> glove_command(const HapticState& state, std::size_t components) {
  std::vector<double> f(components, 0.0);
  const auto& joints = state.finger_joint_angles_rad;
  for (std::size_t i = 0; i + 1 < components && i < 5; ++i) {
    const std::size_t j = std::min(joints.size() - 1, 3 * i + 1);
    f[i] = joints.empty() ? 0.0 : 12.0 * std::max(0.0, joints[j] - 0.3);
  }
  if (components > 5) f[5] = (state.buttons & 1u) != 0 ? 0.4 : 0.0;
  return f;
}

/// Records the session into `path`; returns the number of force commands sent.
inline std::size_t record_sim_session(const std::filesystem::path& path,
                                      const SimSessionOptions& options = {}) {
  using std::chrono::milliseconds;
  TickingClock clock(std::chrono::seconds(1), options.tick_per_reading);
  const Registry registry = builtin_registry();
  ForceGuardConfig guard_config;
  guard_config.ramp_in = milliseconds(40);

  TraceHeader header;
  header.start_time_ns = clock.now().count();
  header.producer = "bisturi tests/trace_fixture.h";
  header.config = force_guard_config_json(guard_config);
  TraceWriter writer(path, header, options.writer);

  SimulatedGlove glove(glove_script(), "GLOVE-0001", options.glove_rate_hz);
  SimulatedHeadTracker head(head_script());
  VirtualPair glove_link = make_virtual_pair(glove.descriptor());
  glove.attach(std::move(glove_link.device));
  RecordedDevice glove_dev = open_recorded(registry, std::move(glove_link.host), writer, clock);
  RecordedDevice head_dev;
  if (options.tracker) {
    VirtualPair head_link = make_virtual_pair(head.descriptor());
    head.attach(std::move(head_link.device));
    head_dev = open_recorded(registry, std::move(head_link.host), writer, clock);
  }
  HapticDevice* haptic = as_haptic(glove_dev.device.get());
  ForceGuard guard(haptic->capabilities().force_channels, guard_config);
  auto guarded = std::make_unique<GuardedHaptic>(*haptic, guard, clock, &writer, glove_dev.index);

  const Nanoseconds t0 = clock.now();
  std::size_t commands = 0;
  bool lost = false;
  for (Nanoseconds t{0}; t < options.duration; t += milliseconds(1)) {
    clock.set(t0 + t);
    if (options.unplug_at.count() > 0 && t == options.unplug_at) glove.disconnect();
    if (lost && t == options.unplug_at + milliseconds(20)) {
      // Plugged back: a new link, the driver opened again as the same trace device.
      guarded.reset();
      glove_dev.device.reset();
      VirtualPair again = make_virtual_pair(glove.descriptor());
      glove.attach(std::move(again.device));
      glove_dev = open_recorded(registry, std::move(again.host), writer, clock, glove_dev.index);
      haptic = as_haptic(glove_dev.device.get());
      guard.rearm();
      guarded = std::make_unique<GuardedHaptic>(*haptic, guard, clock, &writer, glove_dev.index);
      lost = false;
    }
    glove.step(t);
    if (options.tracker) head.step(t);
    if (head_dev.device) head_dev.device->poll(std::chrono::microseconds(0));
    if (lost) continue;
    try {
      guarded->poll(std::chrono::microseconds(0));
      guarded->send(glove_command(haptic->state(), guard.force_components()));
      ++commands;
    } catch (const DeviceDisconnected&) {
      lost = true;
    }
  }
  // The session ends: devices close (zero forces), then the trace.
  guarded.reset();
  glove_dev.device.reset();
  head_dev.device.reset();
  writer.close();
  return commands;
}

}  // namespace bisturi::devices::testing
