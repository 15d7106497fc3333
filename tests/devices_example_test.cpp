// A driver written inside a test, the smallest one the device interfaces allow: a one-finger
// "thimble" with a 1-D force, its simulated twin, and the driver run on the twin's bytes. It keeps
// the 1-component force channel covered; the worked example of docs/adding-a-device.md is the
// built template in devices/sample/.
//
// Protocol (raw USB interrupt packets, 8 bytes, little-endian):
//   in  0x01: [0]=0x01 [1]=buttons [2..3]=joint angle, int16, 1e-4 rad [4..7]=reserved
//   out 0x02: [0]=0x02 [1]=0 [2..3]=force, uint16, mN (0..3000) [4..7]=0
#include <gtest/gtest.h>

#include <cmath>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
using namespace std::chrono_literals;

// ---- The driver -------------------------------------------------------------------------------
namespace thimble {

constexpr std::uint16_t kVendorId = 0x1209, kProductId = 0xB15A;
constexpr double kMaxForceN = 3.0;

class Driver final : public bd::HapticDevice {
 public:
  Driver(std::unique_ptr<bd::Transport> transport, bd::Clock& clock)
      : HapticDevice(std::move(transport), clock), descriptor_(Device::transport().descriptor()) {
    descriptor_.driver = "thimble";
    caps_.device_class = bd::DeviceClass::HapticGlove;
    caps_.buttons = 1;
    caps_.finger_joints = {"index_flexion"};
    caps_.force_channels = {bd::ForceChannel{"index", 1, kMaxForceN, 60.0, false}};
    state_.finger_joint_angles_rad.assign(1, 0.0);
  }
  ~Driver() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const bd::DeviceDescriptor& descriptor() const override { return descriptor_; }
  const bd::Capabilities& capabilities() const override { return caps_; }
  const bd::HapticState& state() const override { return state_; }
  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> p) override {
    if (p.size() != 8) {
      throw bd::ProtocolError(bd::describe(descriptor_), p.size(), "expected 8 bytes");
    }
    if (p[0] != 0x01) throw bd::ProtocolError(bd::describe(descriptor_), 0, "unknown packet type");
    state_.buttons = p[1] & 1u;
    state_.finger_joint_angles_rad[0] = static_cast<std::int16_t>(p[2] | p[3] << 8) * 1e-4;
    ++state_.reports;
    state_.sample_time = clock().now();
  }

  void send_forces(std::span<const double> forces_N) override {
    if (forces_N.size() != 1) throw std::invalid_argument("thimble: one force value");
    const double mN = std::clamp(std::round(forces_N[0] * 1000.0), 0.0, kMaxForceN * 1000.0);
    const auto v = static_cast<std::uint16_t>(mN);
    const std::uint8_t packet[8] = {
        0x02, 0, static_cast<std::uint8_t>(v & 0xFF), static_cast<std::uint8_t>(v >> 8), 0, 0,
        0,    0};
    transport().write(packet);
  }

 private:
  void send_zero() override {
    const double zero = 0;
    send_forces(std::span(&zero, 1));
  }
  std::string name_ = "thimble";
  bd::DeviceDescriptor descriptor_;
  bd::Capabilities caps_;
  bd::HapticState state_;
};

bd::DriverInfo driver_info() {
  bd::DriverInfo info;
  info.name = "thimble";
  info.summary = "one-finger thimble, 1-D force";
  info.usb_ids = {bd::UsbId{kVendorId, kProductId}};
  info.create = [](std::unique_ptr<bd::Transport> t, bd::Clock& c) -> std::unique_ptr<bd::Device> {
    return std::make_unique<Driver>(std::move(t), c);
  };
  return info;
}

// ---- Its simulated twin -----------------------------------------------------------------------
class Twin final : public bd::SimulatedDevice {
 public:
  explicit Twin(bd::DeviceScript script)
      : SimulatedDevice(make_descriptor(), 1ms), script_(std::move(script)) {}
  double force_N() const {
    std::lock_guard lock(mutex_);
    return force_N_;
  }

 private:
  static bd::DeviceDescriptor make_descriptor() {
    bd::DeviceDescriptor d;
    d.kind = bd::TransportKind::Usb;
    d.vendor_id = kVendorId;
    d.product_id = kProductId;
    d.product = "thimble twin";
    d.path = "virtual:thimble";
    return d;
  }
  bd::Bytes input_report(bd::Nanoseconds t) override {
    const auto angle = static_cast<std::int16_t>(std::lround(script_.joints_at(t, 1)[0] * 1e4));
    const auto raw = static_cast<std::uint16_t>(angle);
    return {0x01,
            static_cast<std::uint8_t>(script_.buttons_at(t) & 1),
            static_cast<std::uint8_t>(raw & 0xFF),
            static_cast<std::uint8_t>(raw >> 8),
            0,
            0,
            0,
            0};
  }
  void on_output(std::span<const std::uint8_t> p) override {
    if (p.size() == 8 && p[0] == 0x02) force_N_ = (p[2] | p[3] << 8) / 1000.0;
  }
  bd::DeviceScript script_;
  double force_N_ = 0;
};

}  // namespace thimble

// ---- Its test ---------------------------------------------------------------------------------
TEST(ThimbleExample, DriverOnItsTwinThroughTheRegistryAndTheGuard) {
  bd::DeviceScript script;
  bd::MotionKey open_hand, closed_hand;
  open_hand.joints_rad = {0.0};
  closed_hand.t = 100ms;
  closed_hand.joints_rad = {1.2};
  script.motion = {open_hand, closed_hand};
  script.presses = {{50ms, 0, true}};
  thimble::Twin twin(script);

  bd::Registry registry;
  bd::register_builtin_drivers(registry);
  registry.add(thimble::driver_info());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto device = registry.open(std::move(pair.host), clock);
  ASSERT_EQ(device->driver_name(), "thimble");
  auto* thimble = bd::as_haptic(device.get());

  bd::ForceGuard guard(thimble->capabilities().force_channels);
  double command = 0, out = 0;
  for (int ms = 1; ms <= 400; ++ms) {
    clock.set(std::chrono::milliseconds(ms));
    twin.step(clock.now());
    if (thimble->poll(0us) > 0) guard.device_answered(clock.now());
    // A virtual wall at 0.6 rad: 5 N/rad beyond it (asks for more than the 3 N limit later).
    const double angle = thimble->state().finger_joint_angles_rad[0];
    command = std::max(0.0, angle - 0.6) * 5.0 * (ms > 100 ? 2.0 : 1.0);
    guard.step(std::span(&command, 1), clock.now(), std::span(&out, 1));
    thimble->send_forces(std::span(&out, 1));
  }
  EXPECT_NEAR(thimble->state().finger_joint_angles_rad[0], 1.2, 1e-4);
  EXPECT_EQ(thimble->state().buttons, 1u);
  EXPECT_NEAR(twin.force_N(), 3.0, 1e-3);  // clamped to max_force_N, ramped in at 60 N/s
  thimble->close();
  EXPECT_EQ(twin.force_N(), 0.0);
}
