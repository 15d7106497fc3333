// The sample pinch grip's driver: bytes from the transport to SI units, and forces back.
#include "bisturi/devices/sample/sample_pinch.h"

#include <algorithm>
#include <cmath>
#include <numeric>
#include <stdexcept>

namespace bisturi::devices {

namespace {

namespace pp = pinch_protocol;

// The byte that makes the packet's bytes sum to 0 mod 256.
std::uint8_t balance(std::span<const std::uint8_t> first_15) {
  const unsigned sum = std::accumulate(first_15.begin(), first_15.end(), 0u);
  return static_cast<std::uint8_t>((256u - (sum & 0xFFu)) & 0xFFu);
}

class SamplePinch final : public HapticDevice {
 public:
  SamplePinch(std::unique_ptr<Transport> transport, Clock& clock)
      : HapticDevice(std::move(transport), clock), descriptor_(Device::transport().descriptor()) {
    descriptor_.driver = kSamplePinchDriver;  // replay rebuilds the driver by this name
    caps_.device_class = DeviceClass::HapticGlove;
    caps_.buttons = 1;
    caps_.finger_joints = {"thumb_flexion", "index_flexion"};
    caps_.force_channels = {
        ForceChannel{"thumb", 1, pp::kMaxForceN, pp::kMaxForceRateNPerS, false},
        ForceChannel{"index", 1, pp::kMaxForceN, pp::kMaxForceRateNPerS, false}};
    caps_.spec.max_stiffness_N_per_m = pp::kMaxStiffnessNPerM;  // no pose: no workspace to state
    state_.finger_joint_angles_rad.assign(2, 0.0);
  }
  ~SamplePinch() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const HapticState& state() const override { return state_; }
  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> p) override {
    const std::string device = describe(descriptor_);
    if (p.size() != pp::kPacketSize) {
      throw ProtocolError(device, p.size(),
                          "packet of " + std::to_string(p.size()) + " bytes, expected 16");
    }
    if (balance(p.first(15)) != p[15]) throw ProtocolError(device, 15, "checksum mismatch");
    if (p[0] != pp::kState) {
      throw ProtocolError(device, 0, "unknown packet type " + std::to_string(p[0]));
    }
    state_.buttons = p[2] & 0x01u;
    for (std::size_t j = 0; j < 2; ++j) {
      const auto raw = static_cast<std::uint16_t>(p[4 + 2 * j] | p[5 + 2 * j] << 8);
      state_.finger_joint_angles_rad[j] = static_cast<std::int16_t>(raw) * 1e-4;
    }
    ++state_.reports;
    state_.sample_time = clock().now();
  }

  void send_forces(std::span<const double> forces_N) override {
    expect_force_values(forces_N, 2);
    transport().write(force_packet(forces_N, sequence_++));
  }

 private:
  static std::array<std::uint8_t, pp::kPacketSize> force_packet(std::span<const double> forces_N,
                                                                std::uint8_t sequence) {
    std::array<std::uint8_t, pp::kPacketSize> packet{};
    packet[0] = pp::kForce;
    packet[1] = sequence;
    for (std::size_t i = 0; i < 2; ++i) {
      // An actuator only pulls: a negative or non-finite command is no force.
      const double N =
          std::isfinite(forces_N[i]) ? std::clamp(forces_N[i], 0.0, pp::kMaxForceN) : 0.0;
      const auto mN = static_cast<std::uint16_t>(std::lround(N * 1000.0));
      packet[2 + 2 * i] = static_cast<std::uint8_t>(mN & 0xFF);
      packet[3 + 2 * i] = static_cast<std::uint8_t>(mN >> 8);
    }
    packet[15] = balance(std::span(packet).first(15));
    return packet;
  }

  void send_zero() override {
    const double zero[2] = {0.0, 0.0};
    send_forces(zero);
  }
  // The same packet for the supervisor's preempting zero (the device only counts sequence
  // numbers).
  void zero_reports(std::vector<Bytes>& out) const override {
    const double zero[2] = {0.0, 0.0};
    const auto packet = force_packet(zero, 0);
    out.assign(1, Bytes(packet.begin(), packet.end()));
  }

  std::string name_ = kSamplePinchDriver;
  DeviceDescriptor descriptor_;
  Capabilities caps_;
  HapticState state_;
  std::uint8_t sequence_ = 0;
};

}  // namespace

std::unique_ptr<HapticDevice> open_sample_pinch(std::unique_ptr<Transport> transport,
                                                Clock& clock) {
  if (!transport) throw std::invalid_argument("open_sample_pinch: no transport");
  return std::make_unique<SamplePinch>(std::move(transport), clock);
}

DriverInfo sample_pinch_driver_info() {
  DriverInfo info;
  info.name = kSamplePinchDriver;
  info.summary = "sample two-finger pinch grip on raw USB (the template in devices/sample/)";
  info.usb_ids = {UsbId{pp::kVendorId, pp::kProductId}};
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_sample_pinch(std::move(transport), clock);
  };
  info.bus = TransportKind::Usb;  // the session looks for it with libusb
  // The interface and interrupt endpoints it talks to, as `lsusb -v` lists them for the device
  // (left at {}: the first vendor-specific interface with an interrupt IN and OUT endpoint).
  info.usb_interface = {0, 0x81, 0x01};
  info.device_class = DeviceClass::HapticGlove;
  info.make_twin = [](const DeviceScript& script, const std::string& serial,
                      double haptic_hz) -> std::unique_ptr<SimulatedDevice> {
    return std::make_unique<SimulatedPinch>(script, serial.empty() ? "PINCH-0001" : serial,
                                            haptic_hz);
  };
  info.layout.channels = {ChannelRole{ChannelUse::Finger, 0}, ChannelRole{ChannelUse::Finger, 1}};
  return info;
}

}  // namespace bisturi::devices
