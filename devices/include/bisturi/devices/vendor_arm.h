// "vendor-arm": a vendor-specific haptic arm on raw USB interrupt transfers (libusb), one end
// effector with a 3-D force. Protocol: docs/devices/vendor-haptic-protocol.md.
#pragma once

#include <array>
#include <cstdint>
#include <memory>
#include <span>

#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"

namespace bisturi::devices {

inline constexpr const char* kVendorArmDriver = "vendor-arm";

namespace arm_protocol {
inline constexpr std::uint16_t kVendorId = 0x1209;  // pid.codes
inline constexpr std::uint16_t kProductId = 0xB157;
inline constexpr std::uint8_t kEndpointIn = 0x81;
inline constexpr std::uint8_t kEndpointOut = 0x01;
inline constexpr std::size_t kPacketSize = 32;
inline constexpr std::uint8_t kVersion = 1;
// Device -> host.
inline constexpr std::uint8_t kState = 0x01;
inline constexpr std::uint8_t kInfo = 0x02;
// Host -> device.
inline constexpr std::uint8_t kForce = 0x10;
inline constexpr std::uint8_t kGetInfo = 0x11;
// Status bits in a state packet.
inline constexpr std::uint8_t kStatusForcesActive = 0x01;
inline constexpr std::uint8_t kStatusDeviceWatchdog = 0x02;

// CRC-16/CCITT-FALSE (poly 0x1021, init 0xFFFF) of bytes [0, 30); stored little-endian at 30.
std::uint16_t crc16(std::span<const std::uint8_t> bytes);
void seal(std::span<std::uint8_t, kPacketSize> packet);
using Packet = std::array<std::uint8_t, kPacketSize>;
}  // namespace arm_protocol

struct VendorArmOptions {
  std::chrono::milliseconds info_timeout{500};  // wait for the info answer when opening
};

// Asks the arm for its info packet (limits, buttons) and throws DeviceError when none comes.
std::unique_ptr<HapticDevice> open_vendor_arm(std::unique_ptr<Transport> transport,
                                              Clock& clock = steady_clock(),
                                              VendorArmOptions options = {});
DriverInfo vendor_arm_driver_info();

}  // namespace bisturi::devices
