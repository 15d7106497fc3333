#pragma once
// The live session's injected faults (fault_injection.h): made to happen at their session times
// by the thread that watches the session, acted on by the part they name (the tissue thread and
// the renderer read their flags here), and measured by the haptic thread (the first tick with
// zero force on every channel after each).

#include <atomic>
#include <cstdint>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/runtime/session/fault_injection.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/session_devices.h"
#include "haptic_thread.h"

namespace bisturi::runtime {

class FaultInjector {
 public:
  /// `faults` in any order; outcomes go to report.injected in time order.
  FaultInjector(std::vector<InjectedFault> faults, SessionReport& report, devices::Clock& clock,
                SessionDevices& devices, devices::TraceWriter* writer, double haptic_hz);

  [[nodiscard]] bool any() const { return !faults_.empty(); }
  /// Lets the haptic thread measure the faults (nothing when there are none).
  void watch_with(HapticThreadFlags& flags);
  /// Makes the faults due by `ticks` haptic ticks happen. The watching thread's.
  void poll(std::uint64_t ticks);
  /// The supervisor zeroed the output at clock time `at` (past a stuck tick): the current
  /// fault's zero, unless a tick saw one first. Any thread.
  void zero_went_out(devices::Nanoseconds at);
  /// After the haptic thread ended: the last fault's outcome, and those never made.
  void finish();

  /// Read by the tissue thread's step, the renderer's frame and the blood's thread: set, they
  /// fail as told once.
  std::atomic<bool> hang_tissue{false}, fail_tissue{false}, fail_render{false}, hang_render{false},
      lose_controller{false}, stall_swapchain{false}, stall_blood{false};
  /// Set by the renderer once it presents through OpenXR (a swapchain to stall).
  std::atomic<bool> headset_sink{false};
  /// The haptic device is the headset's controller, fed by the renderer (set before the run).
  bool controller_fed = false;

 private:
  void settle_last();
  void inject(const InjectedFault& f, std::uint64_t ticks);

  std::vector<InjectedFault> faults_;
  std::size_t next_ = 0;
  SessionReport& report_;
  devices::Clock& clock_;
  SessionDevices& devices_;
  devices::TraceWriter* writer_;
  double haptic_hz_;
  std::atomic<std::int64_t> fault_at_ns_{-1}, zero_at_ns_{-1};
  std::atomic<double> output_now_N_{0.0};
};

}  // namespace bisturi::runtime
