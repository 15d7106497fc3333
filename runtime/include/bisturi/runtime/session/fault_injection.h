#pragma once
// Faults a session can be told to suffer (`bisturi run --inject FAULT@SECONDS`), for its tests and
// for integrators checking a new driver: each is made to happen in the part it names, at the
// session time given, and the report says how long the force took to reach zero on every
// channel after it and whether the session went on.

#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

namespace bisturi::runtime {

enum class FaultKind : std::uint8_t {
  TissueHang,     ///< the tissue thread stops inside a step for kFaultHangSeconds
  TissueThrow,    ///< the tissue step throws: no more steps, the session goes on without force
  RenderThrow,    ///< the renderer throws: the session ends on an error
  RenderHang,     ///< a frame stops for kFaultHangSeconds: the picture freezes, the forces stop
  DeviceUnplug,   ///< the haptic device disconnects (a simulated device's link breaks)
  TraceDiskFull,  ///< the trace's next write fails as on a full disk: the recording stops
  TraceSlowDisk,  ///< the trace's writes stall for kFaultHangSeconds: the force path must not
  DeviceIoStall,  ///< the haptic device holds off the host's next write for kFaultHangSeconds
  ControllerTrackingLost,  ///< the headset's controller is not located for kFaultHangSeconds
  HeadsetSwapchainStall,   ///< the headset's next swapchain image wait blocks kFaultHangSeconds
  /// The blood's thread stops inside its next step (the first after a cut opens a vessel, when
  /// none bleeds yet) for kBloodStallSeconds: the blood's clock holds, and the tissue and the
  /// force go on without waiting for it.
  BloodStall,
};

/// How long a hang or a stall lasts.
constexpr double kFaultHangSeconds = 2.0;
/// A blood stall is shorter: it ends within the bleeding that follows a scripted cut.
constexpr double kBloodStallSeconds = 0.5;

const char* to_string(FaultKind kind);
/// Every fault's name, for help texts and errors.
std::string fault_names();

struct InjectedFault {
  FaultKind kind = FaultKind::TissueHang;
  double at_s = 0.0;  ///< session time
};

/// "tissue-hang@2.5". Throws std::invalid_argument naming the text and the faults there are.
InjectedFault parse_fault(std::string_view text);

/// What happened after an injected fault (SessionReport::injected).
struct FaultOutcome {
  InjectedFault fault;
  double injected_s = -1.0;  ///< when it was made to happen (-1: the session ended first)
  /// The largest force on a channel at the tick before it (N): 0 means there was none to remove.
  double force_before_N = 0.0;
  /// From the fault to the first tick with zero force on every channel (ms); -1: none came.
  double zero_after_ms = -1.0;
};

}  // namespace bisturi::runtime
