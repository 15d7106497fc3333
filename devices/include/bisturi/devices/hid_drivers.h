// Generic HID drivers that find everything from the device's report descriptor:
//  - "hid-glove": application collection VR Controls:Glove (0x03:0x04). Hand pose from Generic
//    Desktop X/Y/Z (length unit) and Sensors Orientation Quaternion (0x20:0x0483, x y z w) or
//    Generic Desktop Rx/Ry/Rz (rotation unit); finger joints from VR Controls:Flexor (0x03:0x03,
//    rotation unit); buttons from the Button page; force outputs from PID Magnitude (0x0F:0x70)
//    and Haptics Intensity (0x0E:0x23) output fields, one actuator channel per element (newtons
//    when the field has a force unit, else a fraction of 1).
//    Spec: the workspace is the box the position fields can report (their logical range in
//    SI units); the stiffness is HidGloveOptions' conservative default (HID has no usage for it).
//  - "hid-tracker": VR Controls Head Tracker (0x03:0x05) or Head Mounted Display (0x03:0x06):
//    the same pose inputs, no forces (stiffness 0), the same workspace.
// See docs/adding-a-device.md for what a descriptor needs.
#pragma once

#include <memory>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/device.h"
#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/registry.h"

namespace bisturi::devices {

inline constexpr const char* kHidGloveDriver = "hid-glove";
inline constexpr const char* kHidTrackerDriver = "hid-tracker";

struct HidGloveOptions {
  // HID has no usage for a force slew limit: drivers take it from here.
  double max_force_rate_N_per_s = 200.0;
  // Nor for the stiffest spring the actuators render stably: a conservative default for finger
  // actuators (docs/adding-a-device.md, "Device specs"); set it from a glove's datasheet.
  double max_stiffness_N_per_m = 300.0;
};

// Throw ProtocolError when the descriptor does not parse or describes no glove (no joints, no
// pose, no buttons) / no tracker (no pose).
std::unique_ptr<HapticDevice> open_hid_glove(std::unique_ptr<Transport> transport,
                                             Clock& clock = steady_clock(),
                                             HidGloveOptions options = {});
std::unique_ptr<Tracker> open_hid_tracker(std::unique_ptr<Transport> transport,
                                          Clock& clock = steady_clock());

// Whether a descriptor's report descriptor parses and has the glove / tracker application
// collection (the registry's matches()).
bool describes_hid_glove(const DeviceDescriptor& device);
bool describes_hid_tracker(const DeviceDescriptor& device);

// Whether the generic drivers can use a report descriptor, and why not: what `bisturi device
// describe` prints. `why` is empty when the driver can use it; `found` lists what it would read.
struct GenericHidFit {
  bool glove = false, tracker = false;
  std::string glove_why, tracker_why;
  std::vector<std::string> found;  // "15 finger joints", "pose", "5 force channels (N)", ...
};
// Throws ProtocolError when the descriptor does not parse.
GenericHidFit assess_generic_hid(std::span<const std::uint8_t> report_descriptor);

DriverInfo hid_glove_driver_info();
DriverInfo hid_tracker_driver_info();

}  // namespace bisturi::devices
