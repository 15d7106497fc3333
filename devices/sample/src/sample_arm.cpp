// The sample arm's driver: encoder bytes to a pose in metres, forces in newtons back to bytes.
#include "bisturi/devices/sample/sample_arm.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

namespace bisturi::devices {

namespace {

namespace ap = sample_arm_protocol;

std::uint8_t xor_of(std::span<const std::uint8_t> bytes) {
  std::uint8_t x = 0;
  for (const std::uint8_t b : bytes)
    x ^= b;
  return x;
}

std::int32_t int32_at(std::span<const std::uint8_t> p, std::size_t at) {
  const std::uint32_t u =
      static_cast<std::uint32_t>(p[at]) | static_cast<std::uint32_t>(p[at + 1]) << 8 |
      static_cast<std::uint32_t>(p[at + 2]) << 16 | static_cast<std::uint32_t>(p[at + 3]) << 24;
  return static_cast<std::int32_t>(u);
}

class SampleArm final : public HapticDevice {
 public:
  SampleArm(std::unique_ptr<Transport> transport, Clock& clock)
      : HapticDevice(std::move(transport), clock), descriptor_(Device::transport().descriptor()) {
    descriptor_.driver = kSampleArmDriver;  // replay rebuilds the driver by this name
    caps_.device_class = DeviceClass::HapticArm;
    caps_.end_effectors = 1;
    caps_.buttons = 3;
    // One 3-axis channel, rated per axis as the datasheet states it: the guard lets 8 N through
    // on every axis at once and scales a force beyond that down whole, keeping its direction.
    ForceChannel handle{"handle", 3, ap::kMaxForcePerAxisN, ap::kMaxForceRateNPerS, false};
    handle.per_axis = true;
    caps_.force_channels = {handle};
    caps_.spec.max_stiffness_N_per_m = ap::kMaxStiffnessNPerM;
    caps_.spec.workspace_min_m = {-ap::kWorkspaceHalfWidthM, -ap::kWorkspaceHalfWidthM,
                                  -ap::kWorkspaceHalfHeightM};
    caps_.spec.workspace_max_m = {ap::kWorkspaceHalfWidthM, ap::kWorkspaceHalfWidthM,
                                  ap::kWorkspaceHalfHeightM};
    state_.end_effector_poses.resize(1);
  }
  ~SampleArm() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const HapticState& state() const override { return state_; }
  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> p) override {
    // A bad packet throws before the state changes: the session drops it and counts it.
    if (p.size() != ap::kPacketSize) {
      throw ProtocolError(describe(descriptor_), p.size(),
                          "packet of " + std::to_string(p.size()) + " bytes, expected 24");
    }
    if (xor_of(p.first(23)) != p[23]) {
      throw ProtocolError(describe(descriptor_), 23, "checksum mismatch");
    }
    if (p[0] != ap::kState) {
      throw ProtocolError(describe(descriptor_), 0, "unknown packet type " + std::to_string(p[0]));
    }
    state_.buttons = p[2] & 0x07u;
    Vec3& position = state_.end_effector_poses[0].position_m;
    position = {int32_at(p, 4) * 1e-6, int32_at(p, 8) * 1e-6, int32_at(p, 12) * 1e-6};
    ++state_.reports;
    state_.sample_time = clock().now();
  }

  void send_forces(std::span<const double> forces_N) override {
    expect_force_values(forces_N, 3);
    transport().write(force_packet(forces_N, sequence_++));
  }

 private:
  static std::array<std::uint8_t, ap::kPacketSize> force_packet(std::span<const double> forces_N,
                                                                std::uint8_t sequence) {
    std::array<std::uint8_t, ap::kPacketSize> packet{};
    packet[0] = ap::kForce;
    packet[1] = sequence;
    // The guard has already limited the force; a non-finite value is no force, and the clamp
    // only keeps a value the guard let through inside the int16 the wire carries.
    for (std::size_t i = 0; i < 3; ++i) {
      const double N = std::isfinite(forces_N[i])
                           ? std::clamp(forces_N[i], -ap::kMaxForcePerAxisN, ap::kMaxForcePerAxisN)
                           : 0.0;
      const auto mN =
          static_cast<std::uint16_t>(static_cast<std::int16_t>(std::lround(N * 1000.0)));
      packet[2 + 2 * i] = static_cast<std::uint8_t>(mN & 0xFF);
      packet[3 + 2 * i] = static_cast<std::uint8_t>(mN >> 8);
    }
    packet[23] = xor_of(std::span(packet).first(23));
    return packet;
  }

  void send_zero() override {
    const double zero[3] = {0.0, 0.0, 0.0};
    send_forces(zero);
  }
  // The supervisor's preempting zero: the same packet, made once at start.
  void zero_reports(std::vector<Bytes>& out) const override {
    const double zero[3] = {0.0, 0.0, 0.0};
    const auto packet = force_packet(zero, 0);
    out.assign(1, Bytes(packet.begin(), packet.end()));
  }

  std::string name_ = kSampleArmDriver;
  DeviceDescriptor descriptor_;
  Capabilities caps_;
  HapticState state_;
  std::uint8_t sequence_ = 0;
};

}  // namespace

std::unique_ptr<HapticDevice> open_sample_arm(std::unique_ptr<Transport> transport, Clock& clock) {
  if (!transport) throw std::invalid_argument("open_sample_arm: no transport");
  return std::make_unique<SampleArm>(std::move(transport), clock);
}

DriverInfo sample_arm_driver_info() {
  DriverInfo info;
  info.name = kSampleArmDriver;
  info.summary = "sample 3-DOF arm on raw USB (the arm template in devices/sample/)";
  info.usb_ids = {UsbId{ap::kVendorId, ap::kProductId}};
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_sample_arm(std::move(transport), clock);
  };
  info.bus = TransportKind::Usb;  // the session looks for it with libusb
  info.usb_interface = {0, ap::kEndpointIn, ap::kEndpointOut};
  info.device_class = DeviceClass::HapticArm;
  info.make_twin = [](const DeviceScript& script, const std::string& serial,
                      double haptic_hz) -> std::unique_ptr<SimulatedDevice> {
    return std::make_unique<SimulatedSampleArm>(script, serial.empty() ? "SARM-0001" : serial,
                                                haptic_hz);
  };
  // The handle's force is the instrument's; the grip grasps, the thumb button cuts, and the
  // pedal is the clutch (the instrument stays while the hand re-centres the handle).
  info.layout.channels = {ChannelRole{ChannelUse::Vector, 0}};
  info.layout.buttons = {ButtonUse::Grasp, ButtonUse::Cut, ButtonUse::Clutch};
  return info;
}

}  // namespace bisturi::devices
