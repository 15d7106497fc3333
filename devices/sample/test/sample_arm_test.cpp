// The sample arm's driver on its twin's bytes: opened through the registry by its USB id, its
// handle's pose in metres and its buttons read, a guarded force over its per-axis rating scaled
// down whole (its direction kept) and applied, malformed packets refused with their byte, zero on
// close.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/sample/sample_arm.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
using namespace std::chrono_literals;

namespace {

bd::Registry registry_with_the_arm() {
  bd::Registry registry = bd::builtin_registry();
  registry.add(bd::sample_arm_driver_info());
  return registry;
}

/// The handle moves from the workspace's centre to (30, -20, 45) mm over 100 ms; the grip
/// closes at 40 ms and the pedal at 60 ms.
bd::DeviceScript handle_moving() {
  bd::DeviceScript script;
  bd::MotionKey start, end;
  end.t = 100ms;
  end.pose.position_m = {0.030, -0.020, 0.045};
  script.motion = {start, end};
  script.presses = {{40ms, 0, true}, {60ms, 2, true}};
  return script;
}

struct ArmOnTwin {
  bd::SimulatedSampleArm twin{handle_moving()};
  bd::VirtualClock clock;
  bd::Registry registry = registry_with_the_arm();
  std::unique_ptr<bd::Device> device;
  bd::HapticDevice* arm = nullptr;
  ArmOnTwin() {
    auto pair = bd::make_virtual_pair(twin.descriptor());
    twin.attach(std::move(pair.device));
    device = registry.open(std::move(pair.host), clock);  // by its USB id
    arm = bd::as_haptic(device.get());
  }
};

}  // namespace

TEST(SampleArm, ReadsItsHandleAndButtonsAndDeclaresItsLimits) {
  ArmOnTwin rig;
  ASSERT_NE(rig.arm, nullptr);
  EXPECT_EQ(rig.arm->driver_name(), bd::kSampleArmDriver);
  const bd::Capabilities& caps = rig.arm->capabilities();
  ASSERT_EQ(caps.force_channels.size(), 1u);
  EXPECT_EQ(caps.force_channels[0].components, 3u);
  EXPECT_TRUE(caps.force_channels[0].per_axis);
  EXPECT_EQ(caps.spec.max_stiffness_N_per_m, 1200.0);
  const bd::DriverInfo* info = rig.registry.find_by_name(bd::kSampleArmDriver);
  ASSERT_NE(info, nullptr);
  EXPECT_EQ(info->usb_interface, (bd::UsbInterface{0, 0x81, 0x01}));
  EXPECT_EQ(info->layout.button_uses(caps),
            (std::vector<bd::ButtonUse>{bd::ButtonUse::Grasp, bd::ButtonUse::Cut,
                                        bd::ButtonUse::Clutch}));
  for (int ms = 1; ms <= 120; ++ms) {
    rig.clock.set(std::chrono::milliseconds(ms));
    rig.twin.step(rig.clock.now());
    (void)rig.arm->poll(0us);
  }
  const bd::Vec3 p = rig.arm->state().end_effector_poses.at(0).position_m;
  EXPECT_NEAR(p.x, 0.030, 1e-6);
  EXPECT_NEAR(p.y, -0.020, 1e-6);
  EXPECT_NEAR(p.z, 0.045, 1e-6);
  EXPECT_EQ(rig.arm->state().buttons, 0b101u) << "grip and pedal";
}

TEST(SampleArm, AGuardedForceKeepsItsDirectionWithinTheAxisRating) {
  ArmOnTwin rig;
  bd::ForceGuard guard(rig.arm->capabilities().force_channels);
  // Rising to 12 N along x and 6 N down z over 100 ms (the guard engages on a small command):
  // over the 8 N axis rating, so the guard scales the whole force by 8/12 (8 N and 4 N), never
  // clipping x alone (which would turn it).
  double out[3] = {0.0, 0.0, 0.0};
  for (int ms = 1; ms <= 400; ++ms) {  // past the guard's 250 ms ramp-in
    const double rise = std::min(1.0, (ms - 1) / 100.0);
    const double command[3] = {12.0 * rise, 0.0, -6.0 * rise};
    rig.clock.set(std::chrono::milliseconds(ms));
    rig.twin.step(rig.clock.now());
    if (rig.arm->poll(0us) > 0) guard.device_answered(rig.clock.now());
    guard.step(command, rig.clock.now(), out);
    rig.arm->send_forces(out);
  }
  const auto applied = rig.twin.applied_force_N();
  EXPECT_NEAR(applied[0], 8.0, 2e-3);
  EXPECT_NEAR(applied[1], 0.0, 1e-9);
  EXPECT_NEAR(applied[2], -4.0, 2e-3);
  EXPECT_EQ(rig.twin.rejected_packets(), 0u);
  rig.arm->close();
  EXPECT_EQ(rig.twin.applied_force_N(), (std::array<double, 3>{0.0, 0.0, 0.0}));
}

TEST(SampleArm, MalformedPacketsNameTheirByteAndKeepTheState) {
  ArmOnTwin rig;
  rig.twin.step(50ms);
  ASSERT_EQ(rig.arm->poll(0us), 1u);
  const bd::HapticState before = rig.arm->state();
  bd::Bytes packet(24, 0);
  packet[0] = 0x11;
  packet[4] = 0x40;  // the XOR is 0x51: byte 23 should be 0x51
  try {
    rig.arm->handle_report(packet);
    ADD_FAILURE() << "a bad checksum was accepted";
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 23u);
  }
  packet[0] = 0x13;
  packet[23] = 0x13 ^ 0x40;
  try {
    rig.arm->handle_report(packet);
    ADD_FAILURE() << "an unknown packet type was accepted";
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 0u);
  }
  EXPECT_THROW(rig.arm->handle_report(bd::Bytes(16, 0)), bd::ProtocolError);
  EXPECT_EQ(rig.arm->state().end_effector_poses[0].position_m.x,
            before.end_effector_poses[0].position_m.x);
  EXPECT_THROW(rig.arm->send_forces(std::vector<double>{1.0, 2.0}), std::invalid_argument);
}
