// "sample-pinch": the template for a new device (docs/adding-a-device.md walks through it). A
// two-finger pinch grip on raw USB interrupt transfers: thumb and index flexion, one button, and a
// 1-D force on each finger. Copy this folder, rename, change the bytes.
//
// Protocol (16-byte packets, little-endian; byte 15 makes the sum of all 16 bytes 0 mod 256):
//   device -> host, every millisecond:
//     0x01 state: [1] sequence (wraps) [2] buttons, bit 0 [3] 0
//                 [4..5] thumb flexion, [6..7] index flexion: int16, 1e-4 rad (0 = open hand)
//   host -> device:
//     0x02 force: [1] sequence [2..3] thumb force, [4..5] index force: uint16 mN, 0..4000
//   A force packet with a bad checksum or a force above 4 N is ignored by the device.
// Datasheet: 4 N per finger, 100 N/s slew, 400 N/m stiffest stable spring at 1 kHz, no pose.
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

inline constexpr const char* kSamplePinchDriver = "sample-pinch";

namespace pinch_protocol {
// pid.codes' 0x1209 with a product id no real device uses: give yours its own ids.
inline constexpr std::uint16_t kVendorId = 0x1209;
inline constexpr std::uint16_t kProductId = 0xB15C;
inline constexpr std::size_t kPacketSize = 16;
inline constexpr std::uint8_t kState = 0x01;
inline constexpr std::uint8_t kForce = 0x02;
inline constexpr double kMaxForceN = 4.0;
inline constexpr double kMaxForceRateNPerS = 100.0;
inline constexpr double kMaxStiffnessNPerM = 400.0;
}  // namespace pinch_protocol

// Throws std::invalid_argument without a transport.
std::unique_ptr<HapticDevice> open_sample_pinch(std::unique_ptr<Transport> transport,
                                                Clock& clock = steady_clock());
// The one thing the registry needs: bus, factory, twin, channel layout.
DriverInfo sample_pinch_driver_info();

// Its twin: joint 0 of the script is the thumb, joint 1 the index; it applies the forces the host
// sends (rejecting what the real device rejects) and counts what it refused.
class SimulatedPinch final : public SimulatedDevice {
 public:
  explicit SimulatedPinch(DeviceScript script, std::string serial = "PINCH-0001",
                          double rate_hz = 1000.0);
  // The forces the device applies now, thumb and index, in newtons.
  std::array<double, 2> applied_forces_N() const;
  std::uint64_t rejected_packets() const;

 private:
  Bytes input_report(Nanoseconds t) override;
  void on_output(std::span<const std::uint8_t> report) override;
  DeviceScript script_;
  std::array<double, 2> forces_N_{};
  std::uint64_t rejected_ = 0;
  std::uint8_t sequence_ = 0;
};

}  // namespace bisturi::devices
