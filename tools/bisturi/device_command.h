#pragma once
// `bisturi device list|describe|check`: what an integrator needs to see about hardware.
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
//   check DRIVER [--seconds S] [--max-force-N F] [--rotation-deg X Y Z] [--translation-mm X Y Z]
//         [--json]              the driver against its twin through the force guard and the haptic
//                                 loop, following the default procedure on the default organ in
//                                 virtual time: poses in the scene, commands and what the guard
//                                 let through per channel against its limits, clamps, rate
//                                 limiting, latches, events (runtime/session/device_check.h)
//   udev-rules                    udev rules giving the user access to the devices the drivers
//                                 claim (by their USB ids), generated from the registry

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct DeviceOptions {
  std::string input;  ///< describe: the descriptor file; check: the driver
  bool json = false;
  double seconds = 4.0;
  double max_force_N = 3.0;
  std::vector<double> rotation_deg{0.0, 0.0, 0.0};
  std::vector<double> translation_mm{0.0, 0.0, 0.0};
};

/// Adds the `device` command with its sub-commands; `run` is set to the one parsed.
void add_device_command(CLI::App& app, DeviceOptions& options, int (*&run)(const DeviceOptions&));

int run_device_list(const DeviceOptions& options);
int run_device_describe(const DeviceOptions& options);
int run_device_check(const DeviceOptions& options);
int run_device_udev_rules(const DeviceOptions& options);
/// Adds `device check` to the `device` command.
void add_device_check_command(CLI::App& device, DeviceOptions& options,
                              int (*&run)(const DeviceOptions&));

}  // namespace bisturi::cli
