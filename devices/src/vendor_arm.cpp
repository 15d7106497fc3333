#include "bisturi/devices/vendor_arm.h"

#include <cmath>
#include <cstring>
#include <stdexcept>

#include "bisturi/devices/simulated.h"

namespace bisturi::devices {

namespace arm_protocol {

std::uint16_t crc16(std::span<const std::uint8_t> bytes) {
  std::uint16_t crc = 0xFFFF;
  for (std::uint8_t byte : bytes) {
    crc = static_cast<std::uint16_t>(crc ^ (std::uint16_t{byte} << 8));
    for (int bit = 0; bit < 8; ++bit) {
      crc = (crc & 0x8000) ? static_cast<std::uint16_t>((crc << 1) ^ 0x1021)
                           : static_cast<std::uint16_t>(crc << 1);
    }
  }
  return crc;
}

void seal(std::span<std::uint8_t, kPacketSize> packet) {
  const std::uint16_t crc = crc16(packet.first(30));
  packet[30] = static_cast<std::uint8_t>(crc & 0xFF);
  packet[31] = static_cast<std::uint8_t>(crc >> 8);
}

}  // namespace arm_protocol

namespace {

namespace ap = arm_protocol;

std::int32_t le32(std::span<const std::uint8_t> p, std::size_t at) {
  return static_cast<std::int32_t>(std::uint32_t{p[at]} | std::uint32_t{p[at + 1]} << 8 |
                                   std::uint32_t{p[at + 2]} << 16 | std::uint32_t{p[at + 3]} << 24);
}
std::uint16_t le16u(std::span<const std::uint8_t> p, std::size_t at) {
  return static_cast<std::uint16_t>(p[at] | p[at + 1] << 8);
}
std::int16_t le16(std::span<const std::uint8_t> p, std::size_t at) {
  return static_cast<std::int16_t>(le16u(p, at));
}

class VendorArm final : public HapticDevice {
 public:
  VendorArm(std::unique_ptr<Transport> transport, Clock& clock, VendorArmOptions options)
      : HapticDevice(std::move(transport), clock), descriptor_(Device::transport().descriptor()) {
    descriptor_.driver = kVendorArmDriver;
    ap::Packet request{};
    request[0] = ap::kGetInfo;
    ap::seal(request);
    Device::transport().write(request);
    const auto deadline = std::chrono::steady_clock::now() + options.info_timeout;
    while (!have_info_) {
      const auto left = std::chrono::duration_cast<std::chrono::microseconds>(
          deadline - std::chrono::steady_clock::now());
      if (left.count() <= 0) break;
      auto packet = Device::transport().read(left);
      if (!packet) break;
      handle_report(*packet);
    }
    if (!have_info_) {
      throw DeviceError(describe(descriptor_) + ": no info packet within " +
                        std::to_string(options.info_timeout.count()) + " ms");
    }
    state_.end_effector_poses.resize(1);
  }
  ~VendorArm() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const HapticState& state() const override { return state_; }
  std::uint8_t status() const { return status_; }

  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> p) override {
    // The device's description is made only for an error: a report costs no allocation.
    const auto device = [this] { return describe(descriptor_); };
    if (p.size() != ap::kPacketSize) {
      throw ProtocolError(device(), p.size(),
                          "packet of " + std::to_string(p.size()) + " bytes, expected 32");
    }
    const std::uint16_t crc = ap::crc16(p.first(30));
    if (le16u(p, 30) != crc) throw ProtocolError(device(), 30, "checksum mismatch");
    if (p[0] == ap::kInfo) {
      if (p[1] != ap::kVersion) {
        throw ProtocolError(device(), 1, "protocol version " + std::to_string(p[1]));
      }
      const double max_force_N = le16u(p, 2) / 100.0;
      const double max_rate = le16u(p, 4);
      if (!(max_force_N > 0) || !(max_rate > 0)) {
        throw ProtocolError(device(), 2, "info packet with a zero force or rate limit");
      }
      caps_ = Capabilities{};
      caps_.device_class = DeviceClass::HapticArm;
      caps_.end_effectors = 1;
      caps_.buttons = std::min<std::size_t>(p[6], 16);
      // Byte 21 bit 0: the force limit holds per axis (0 from firmware that predates it: norm).
      ForceChannel channel{"end_effector", 3, max_force_N, max_rate, false};
      channel.per_axis = (p[21] & 1u) != 0;
      caps_.force_channels.push_back(channel);
      // Bytes 7-20: stiffness and workspace; zeros from firmware that does not state them.
      caps_.spec.max_stiffness_N_per_m = le16u(p, 7);
      const double lo[3] = {le16(p, 9) * 1e-3, le16(p, 11) * 1e-3, le16(p, 13) * 1e-3};
      const double hi[3] = {le16(p, 15) * 1e-3, le16(p, 17) * 1e-3, le16(p, 19) * 1e-3};
      for (std::size_t i = 0; i < 3; ++i) {
        if (lo[i] > hi[i]) {
          throw ProtocolError(device(), 9 + 2 * i,
                              "info packet with a workspace minimum above its maximum");
        }
      }
      caps_.spec.workspace_min_m = {lo[0], lo[1], lo[2]};
      caps_.spec.workspace_max_m = {hi[0], hi[1], hi[2]};
      have_info_ = true;
      return;
    }
    if (p[0] != ap::kState) {
      throw ProtocolError(device(), 0, "unknown packet type " + std::to_string(p[0]));
    }
    if (state_.end_effector_poses.empty()) state_.end_effector_poses.resize(1);
    Pose& pose = state_.end_effector_poses[0];
    pose.position_m = {le32(p, 4) * 1e-6, le32(p, 8) * 1e-6, le32(p, 12) * 1e-6};
    Quaternion q{le16(p, 16) / 16384.0, le16(p, 18) / 16384.0, le16(p, 20) / 16384.0,
                 le16(p, 22) / 16384.0};
    const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
    if (!(n > 1e-3)) throw ProtocolError(device(), 16, "orientation quaternion of zero length");
    pose.orientation = {q.w / n, q.x / n, q.y / n, q.z / n};
    state_.buttons = le16u(p, 2);
    status_ = p[24];
    ++state_.reports;
    state_.sample_time = clock().now();
  }

  void send_forces(std::span<const double> forces_N) override {
    expect_force_values(forces_N, 3);
    transport().write(force_packet(forces_N, sequence_++));
  }

 private:
  static ap::Packet force_packet(std::span<const double> forces_N, std::uint8_t sequence) {
    ap::Packet packet{};
    packet[0] = ap::kForce;
    packet[1] = sequence;
    for (std::size_t i = 0; i < 3; ++i) {
      const double mN = std::isfinite(forces_N[i]) ? std::round(forces_N[i] * 1000.0) : 0.0;
      const auto v = static_cast<std::int16_t>(std::clamp(mN, -32767.0, 32767.0));
      const auto u = static_cast<std::uint16_t>(v);
      packet[2 + 2 * i] = static_cast<std::uint8_t>(u & 0xFF);
      packet[3 + 2 * i] = static_cast<std::uint8_t>(u >> 8);
    }
    ap::seal(packet);
    return packet;
  }

  void send_zero() override {
    const double zero[3] = {0, 0, 0};
    send_forces(zero);
  }
  // The arm does not order force packets by their sequence number (it only counts them).
  void zero_reports(std::vector<Bytes>& out) const override {
    const double zero[3] = {0, 0, 0};
    const ap::Packet packet = force_packet(zero, 0);
    out.assign(1, Bytes(packet.begin(), packet.end()));
  }

  std::string name_ = kVendorArmDriver;
  DeviceDescriptor descriptor_;
  Capabilities caps_;
  HapticState state_;
  bool have_info_ = false;
  std::uint8_t status_ = 0;
  std::uint8_t sequence_ = 0;
};

}  // namespace

std::unique_ptr<HapticDevice> open_vendor_arm(std::unique_ptr<Transport> transport, Clock& clock,
                                              VendorArmOptions options) {
  if (!transport) throw std::invalid_argument("open_vendor_arm: no transport");
  return std::make_unique<VendorArm>(std::move(transport), clock, options);
}

DriverInfo vendor_arm_driver_info() {
  DriverInfo info;
  info.name = kVendorArmDriver;
  info.summary = "vendor haptic arm over USB interrupt transfers (3-D force, pose, buttons)";
  info.usb_ids = {UsbId{ap::kVendorId, ap::kProductId}};
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_vendor_arm(std::move(transport), clock);
  };
  info.bus = TransportKind::Usb;
  // Interface 0, vendor-specific: interrupt IN 0x81 (state packets), interrupt OUT 0x01 (forces).
  info.usb_interface = {0, ap::kEndpointIn, ap::kEndpointOut};
  info.device_class = DeviceClass::HapticArm;
  info.make_twin = [](const DeviceScript& script, const std::string& serial,
                      double haptic_hz) -> std::unique_ptr<SimulatedDevice> {
    return std::make_unique<SimulatedArm>(script, serial.empty() ? "ARM-0001" : serial, haptic_hz);
  };
  info.layout.channels = {ChannelRole{ChannelUse::Vector, 0}};  // the end effector's force
  // The handle's grip closes the grasper; its second button is the scalpel's.
  info.layout.buttons = {ButtonUse::Grasp, ButtonUse::Cut};
  return info;
}

}  // namespace bisturi::devices
