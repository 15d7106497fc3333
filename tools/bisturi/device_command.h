#pragma once
// `bisturi device list|describe`: what an integrator needs to see about hardware.
//   list [--json]                 HID devices (hidapi) and vendor-specific USB devices (libusb)
//                                 connected now, and which registered driver claims each; works
//                                 with none connected
//   describe DESCRIPTOR.bin [--json]
//                                 a HID report descriptor (raw bytes, as in
//                                 /sys/class/hidraw/hidrawN/device/report_descriptor): its reports
//                                 by type and id with sizes in bits and bytes, fields, usages,
//                                 warnings, and whether the generic glove or tracker driver can
//                                 use it (and why not). Malformed: exit 2, naming the byte offset
//                                 and the item.

#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct DeviceOptions {
  std::string input;
  bool json = false;
};

/// Adds the `device` command with its sub-commands; `run` is set to the one parsed.
void add_device_command(CLI::App& app, DeviceOptions& options, int (*&run)(const DeviceOptions&));

int run_device_list(const DeviceOptions& options);
int run_device_describe(const DeviceOptions& options);

}  // namespace bisturi::cli
