#pragma once
// The devices of a trace with their drivers rebuilt, as replay does, on transports fed nothing
// but what the trace holds: `trace dump` decodes reports through them, `trace forces` reads
// their force channels.

#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/hid_report.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/trace_format.h"

namespace bisturi::cli {

struct DecodedDevice {
  devices::TraceDevice trace;
  devices::VirtualClock clock;
  std::unique_ptr<devices::Device> driver;  ///< null when it would not open (driver_error)
  std::string driver_error;
  std::optional<devices::hid::ReportCodec> codec;  ///< HID devices: their report descriptor
};

/// Every device of the trace at `path`, in trace order. A driver that asks the device something
/// when it opens (the arm's info packet) finds the recorded answers queued.
std::vector<std::unique_ptr<DecodedDevice>> decode_trace_devices(const std::string& path,
                                                                 const devices::Registry& registry);

}  // namespace bisturi::cli
