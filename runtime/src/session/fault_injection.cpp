// Injected faults: their names (see fault_injection.h).

#include "bisturi/runtime/session/fault_injection.h"

#include <array>
#include <cmath>
#include <stdexcept>

namespace bisturi::runtime {

namespace {

constexpr std::array<FaultKind, 11> kAll = {FaultKind::TissueHang,
                                            FaultKind::TissueThrow,
                                            FaultKind::RenderThrow,
                                            FaultKind::RenderHang,
                                            FaultKind::DeviceUnplug,
                                            FaultKind::DeviceIoStall,
                                            FaultKind::TraceDiskFull,
                                            FaultKind::TraceSlowDisk,
                                            FaultKind::ControllerTrackingLost,
                                            FaultKind::HeadsetSwapchainStall,
                                            FaultKind::BloodStall};

}  // namespace

const char* to_string(FaultKind kind) {
  switch (kind) {
    case FaultKind::TissueHang:
      return "tissue-hang";
    case FaultKind::TissueThrow:
      return "tissue-throw";
    case FaultKind::RenderThrow:
      return "render-throw";
    case FaultKind::RenderHang:
      return "render-hang";
    case FaultKind::DeviceUnplug:
      return "device-unplug";
    case FaultKind::TraceDiskFull:
      return "trace-disk-full";
    case FaultKind::TraceSlowDisk:
      return "trace-slow-disk";
    case FaultKind::DeviceIoStall:
      return "device-io-stall";
    case FaultKind::ControllerTrackingLost:
      return "controller-tracking-lost";
    case FaultKind::HeadsetSwapchainStall:
      return "headset-swapchain-stall";
    case FaultKind::BloodStall:
      return "blood-stall";
  }
  return "?";
}

std::string fault_names() {
  std::string out;
  for (const FaultKind k : kAll)
    out += (out.empty() ? "" : ", ") + std::string(to_string(k));
  return out;
}

InjectedFault parse_fault(std::string_view text) {
  const auto bad = [&](const std::string& why) {
    return std::invalid_argument("--inject " + std::string(text) + ": " + why +
                                 " (FAULT@SECONDS, FAULT one of " + fault_names() + ")");
  };
  const std::size_t at = text.find('@');
  if (at == std::string_view::npos) throw bad("no '@'");
  const std::string_view name = text.substr(0, at);
  InjectedFault fault;
  bool known = false;
  for (const FaultKind k : kAll) {
    if (name == to_string(k)) {
      fault.kind = k;
      known = true;
    }
  }
  if (!known) throw bad("unknown fault '" + std::string(name) + "'");
  const std::string seconds(text.substr(at + 1));
  std::size_t used = 0;
  try {
    fault.at_s = std::stod(seconds, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used == 0 || used != seconds.size() || !std::isfinite(fault.at_s) || fault.at_s < 0.0)
    throw bad("'" + seconds + "' is not a time in seconds");
  return fault;
}

}  // namespace bisturi::runtime
