// The live session's injected faults (see fault_injector.h).

#include "fault_injector.h"

#include <algorithm>
#include <chrono>

namespace bisturi::runtime {

FaultInjector::FaultInjector(std::vector<InjectedFault> faults, SessionReport& report,
                             devices::Clock& clock, SessionDevices& devices,
                             devices::TraceWriter* writer, double haptic_hz)
    : faults_(std::move(faults)),
      report_(report),
      clock_(clock),
      devices_(devices),
      writer_(writer),
      haptic_hz_(haptic_hz) {
  std::stable_sort(faults_.begin(), faults_.end(),
                   [](const InjectedFault& a, const InjectedFault& b) { return a.at_s < b.at_s; });
}

void FaultInjector::watch_with(HapticThreadFlags& flags) {
  if (faults_.empty()) return;
  flags.fault_at_ns = &fault_at_ns_;
  flags.zero_at_ns = &zero_at_ns_;
  flags.output_now_N = &output_now_N_;
}

void FaultInjector::poll(std::uint64_t ticks) {
  const double session_s = static_cast<double>(ticks) / haptic_hz_;
  while (next_ < faults_.size() && faults_[next_].at_s <= session_s)
    inject(faults_[next_++], ticks);
}

void FaultInjector::finish() {
  settle_last();
  for (; next_ < faults_.size(); ++next_)  // the session ended first
    report_.injected.push_back(FaultOutcome{faults_[next_]});
}

void FaultInjector::zero_went_out(devices::Nanoseconds at) {
  // The supervisor's zero past a stuck tick: the haptic thread cannot see it before it returns.
  if (fault_at_ns_.load() < 0) return;
  std::int64_t none = -1;
  zero_at_ns_.compare_exchange_strong(none, at.count());
}

void FaultInjector::settle_last() {
  if (report_.injected.empty()) return;
  FaultOutcome& o = report_.injected.back();
  const std::int64_t at = fault_at_ns_.load(), zero = zero_at_ns_.load();
  if (at >= 0 && zero >= at) o.zero_after_ms = static_cast<double>(zero - at) * 1e-6;
}

void FaultInjector::inject(const InjectedFault& f, std::uint64_t ticks) {
  settle_last();
  FaultOutcome o;
  o.fault = f;
  o.injected_s = static_cast<double>(ticks) / haptic_hz_;
  o.force_before_N = output_now_N_.load();
  zero_at_ns_.store(-1);
  fault_at_ns_.store(clock_.now().count());
  switch (f.kind) {
    case FaultKind::TissueHang:
      hang_tissue.store(true);
      break;
    case FaultKind::TissueThrow:
      fail_tissue.store(true);
      break;
    case FaultKind::RenderThrow:
      fail_render.store(true);
      break;
    case FaultKind::RenderHang:
      hang_render.store(true);
      break;
    case FaultKind::BloodStall:
      stall_blood.store(true);
      break;
    case FaultKind::HeadsetSwapchainStall:
      if (headset_sink.load()) {
        stall_swapchain.store(true);
      } else {
        o.injected_s = -1.0;  // frames go to files: no swapchain to stall
      }
      break;
    case FaultKind::ControllerTrackingLost:
      if (controller_fed) {
        lose_controller.store(true);
      } else {
        o.injected_s = -1.0;  // no controller to lose
      }
      break;
    case FaultKind::DeviceUnplug:
      if (!devices_.unplug_haptic()) o.injected_s = -1.0;  // hardware: not ours to pull
      break;
    case FaultKind::TraceDiskFull:
      if (writer_ != nullptr) writer_->fail_next_write("No space left on device (injected fault)");
      break;
    case FaultKind::DeviceIoStall:
      if (!devices_.stall_haptic_io(
              std::chrono::milliseconds(static_cast<std::int64_t>(kFaultHangSeconds * 1000.0))))
        o.injected_s = -1.0;  // hardware: not ours to stall
      break;
    case FaultKind::TraceSlowDisk:
      if (writer_ != nullptr)
        writer_->stall_next_write(
            std::chrono::milliseconds(static_cast<std::int64_t>(kFaultHangSeconds * 1000.0)));
      break;
  }
  report_.injected.push_back(o);
}

}  // namespace bisturi::runtime
