// The sample pinch grip's driver on its twin's bytes: opened through the registry (by its USB id
// and by its registered twin), its joints and button read, guarded forces sent and applied, its
// malformed packets refused with the byte offset, zero on close.
#include <gtest/gtest.h>

#include <cmath>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/sample/sample_pinch.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
using namespace std::chrono_literals;

namespace {

// The built-in drivers and this one, as an integrator's program registers its own driver.
bd::Registry registry_with_the_sample() {
  bd::Registry registry = bd::builtin_registry();
  registry.add(bd::sample_pinch_driver_info());
  return registry;
}

bd::DeviceScript pinch_closing() {
  bd::DeviceScript script;
  bd::MotionKey open_hand, closed;
  open_hand.joints_rad = {0.0, 0.0};
  closed.t = 100ms;
  closed.joints_rad = {0.9, 1.3};
  script.motion = {open_hand, closed};
  script.presses = {{40ms, 0, true}};
  return script;
}

}  // namespace

TEST(SamplePinch, RunsOnItsTwinThroughTheRegistryAndTheGuard) {
  bd::SimulatedPinch twin(pinch_closing());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  const bd::Registry registry = registry_with_the_sample();
  auto device = registry.open(std::move(pair.host), clock);  // by its USB id
  ASSERT_EQ(device->driver_name(), bd::kSamplePinchDriver);
  auto* pinch = bd::as_haptic(device.get());
  ASSERT_NE(pinch, nullptr);
  const bd::Capabilities& caps = pinch->capabilities();
  ASSERT_EQ(caps.force_channels.size(), 2u);
  EXPECT_EQ(caps.spec.max_stiffness_N_per_m, 400.0);
  // The registry says what each channel carries: thumb, then index.
  const auto roles = registry.find_by_name(bd::kSamplePinchDriver)->layout.roles(caps);
  ASSERT_EQ(roles.size(), 2u);
  EXPECT_EQ(roles[0], (bd::ChannelRole{bd::ChannelUse::Finger, 0}));
  EXPECT_EQ(roles[1], (bd::ChannelRole{bd::ChannelUse::Finger, 1}));

  bd::ForceGuard guard(caps.force_channels);
  double command[2] = {0, 0}, out[2] = {0, 0};
  for (int ms = 1; ms <= 300; ++ms) {
    clock.set(std::chrono::milliseconds(ms));
    twin.step(clock.now());
    if (pinch->poll(0us) > 0) guard.device_answered(clock.now());
    // Each finger presses its own wall: the thumb at 0.5 rad, the index at 0.8 rad, 10 N/rad.
    const auto& joints = pinch->state().finger_joint_angles_rad;
    command[0] = std::max(0.0, joints[0] - 0.5) * 10.0;
    command[1] = std::max(0.0, joints[1] - 0.8) * 10.0;
    guard.step(command, clock.now(), out);
    pinch->send_forces(out);
  }
  EXPECT_NEAR(pinch->state().finger_joint_angles_rad[0], 0.9, 1e-4);
  EXPECT_NEAR(pinch->state().finger_joint_angles_rad[1], 1.3, 1e-4);
  EXPECT_EQ(pinch->state().buttons, 1u);
  const auto applied = twin.applied_forces_N();
  EXPECT_NEAR(applied[0], 4.0, 1e-3);  // (0.9 - 0.5) * 10 = 4 N: the limit
  EXPECT_NEAR(applied[1], 4.0, 1e-3);  // 5 N asked, clamped to 4 N
  EXPECT_EQ(twin.rejected_packets(), 0u);
  pinch->close();
  EXPECT_EQ(twin.applied_forces_N(), (std::array<double, 2>{0.0, 0.0}));
}

TEST(SamplePinch, MalformedPacketsNameTheirByteAndKeepTheState) {
  bd::SimulatedPinch twin(pinch_closing());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto pinch = bd::open_sample_pinch(std::move(pair.host), clock);
  twin.step(50ms);
  ASSERT_EQ(pinch->poll(0us), 1u);
  const double before = pinch->state().finger_joint_angles_rad[1];
  bd::Bytes packet(16, 0);
  packet[0] = 0x01;
  packet[4] = 0x10;  // the sum is 0x11: byte 15 should be 0xEF
  try {
    pinch->handle_report(packet);
    ADD_FAILURE() << "a bad checksum was accepted";
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 15u);
  }
  packet[15] = 0xEF;
  packet[0] = 0x07;
  packet[15] = static_cast<std::uint8_t>(0xEF - 6);  // type 7, sum still zero
  try {
    pinch->handle_report(packet);
    ADD_FAILURE() << "an unknown packet type was accepted";
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 0u);
  }
  EXPECT_THROW(pinch->handle_report(bd::Bytes(15, 0)), bd::ProtocolError);
  EXPECT_EQ(pinch->state().finger_joint_angles_rad[1], before);
  EXPECT_THROW(pinch->send_forces(std::vector<double>{1.0}), std::invalid_argument);
}

TEST(SamplePinch, TheRegisteredTwinIsWhatASimulatedSceneDeviceOpens) {
  const bd::Registry registry = registry_with_the_sample();
  const bd::DriverInfo* info = registry.find_by_name(bd::kSamplePinchDriver);
  ASSERT_NE(info, nullptr);
  EXPECT_EQ(info->bus, bd::TransportKind::Usb);
  ASSERT_TRUE(info->make_twin);
  auto twin = info->make_twin(pinch_closing(), "PINCH-42", 1000.0);
  EXPECT_EQ(twin->descriptor().serial, "PINCH-42");
  auto pair = bd::make_virtual_pair(twin->descriptor());
  twin->attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto device = registry.open(std::move(pair.host), clock);
  EXPECT_EQ(device->driver_name(), bd::kSamplePinchDriver);
  twin->step(100ms);
  EXPECT_EQ(device->poll(0us), 1u);
}
