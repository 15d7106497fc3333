// "sample-arm": the template for a grounded arm (docs/adding-a-device.md walks through it). A
// 3-DOF arm on raw USB interrupt transfers: the handle's position from the encoders, three
// buttons (grip, a thumb button, a clutch pedal) and a 3-D force at the handle, rated per axis.
// Copy this driver, rename it, change the bytes.
//
// Protocol (24-byte packets, little-endian; byte 23 is the XOR of bytes 0-22):
//   device -> host, every millisecond:
//     0x11 state: [1] sequence (wraps) [2] buttons: bit 0 grip, bit 1 thumb, bit 2 clutch pedal
//                 [3] 0  [4..7] x, [8..11] y, [12..15] z: int32 micrometres in the arm's frame
//                 (origin at the workspace's centre, +z up from the base)  [16..22] 0
//   host -> device:
//     0x12 force: [1] sequence [2..3] fx, [4..5] fy, [6..7] fz: int16 millinewtons, the force on
//                 the hand in the arm's frame, each within +-8000  [8..22] 0
//   A force packet with a bad checksum or an axis beyond 8 N is ignored by the device.
// Datasheet: 8 N per axis (continuous), 400 N/s slew, 1200 N/m stiffest stable spring at 1 kHz,
// workspace 160 x 160 x 120 mm about its centre.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <string>

#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"

namespace bisturi::devices {

inline constexpr const char* kSampleArmDriver = "sample-arm";

namespace sample_arm_protocol {
// pid.codes' 0x1209 with a product id no real device uses: give yours its own ids.
inline constexpr std::uint16_t kVendorId = 0x1209;
inline constexpr std::uint16_t kProductId = 0xB15D;
inline constexpr std::uint8_t kEndpointIn = 0x81;
inline constexpr std::uint8_t kEndpointOut = 0x01;
inline constexpr std::size_t kPacketSize = 24;
inline constexpr std::uint8_t kState = 0x11;
inline constexpr std::uint8_t kForce = 0x12;
inline constexpr double kMaxForcePerAxisN = 8.0;
inline constexpr double kMaxForceRateNPerS = 400.0;
inline constexpr double kMaxStiffnessNPerM = 1200.0;
inline constexpr double kWorkspaceHalfWidthM = 0.08;   // x and y
inline constexpr double kWorkspaceHalfHeightM = 0.06;  // z
}  // namespace sample_arm_protocol

// Throws std::invalid_argument without a transport.
std::unique_ptr<HapticDevice> open_sample_arm(std::unique_ptr<Transport> transport,
                                              Clock& clock = steady_clock());
// What the registry needs: bus, USB ids and interface, factory, twin, channel and button roles.
DriverInfo sample_arm_driver_info();

// Its twin: the script's pose is the handle's position (in the arm's frame), its buttons the
// arm's; it applies the forces the host sends (refusing what the real arm refuses).
class SimulatedSampleArm final : public SimulatedDevice {
 public:
  explicit SimulatedSampleArm(DeviceScript script, std::string serial = "SARM-0001",
                              double rate_hz = 1000.0);
  // The force the motors apply now, in the arm's frame, in newtons.
  std::array<double, 3> applied_force_N() const;
  std::uint64_t rejected_packets() const;

 private:
  Bytes input_report(Nanoseconds t) override;
  void on_output(std::span<const std::uint8_t> report) override;
  DeviceScript script_;
  std::array<double, 3> force_N_{};
  std::uint64_t rejected_ = 0;
  std::uint8_t sequence_ = 0;
};

}  // namespace bisturi::devices
