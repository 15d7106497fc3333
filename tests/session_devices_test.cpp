// The session's devices: which scene device drives the instruments, how real hardware
// is found among the devices a source lists (by driver, vendor/product id and serial), and that a
// simulated haptic arm drives a session through the same registry as a glove.

#include <gtest/gtest.h>

#include <string>

#include "bisturi/devices/controller/openxr_controller.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/sample/sample_pinch.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/transport.h"
#include "bisturi/runtime/session/session_devices.h"

namespace bisturi::runtime {
namespace {

const char* kDevices = R"(
[[devices]]
name = "left"
driver = "hid-glove"
role = "haptic"

[[devices]]
name = "right"
driver = "vendor-arm"
role = "haptic"

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)";

std::string error_of(const std::string& toml) {
  try {
    (void)choose_session_devices(parse_scene(toml, "scene.toml"));
  } catch (const SceneFileError& e) {
    return e.what();
  }
  return "no error";
}

TEST(SessionDevices, InstrumentsChooseTheHapticDevice) {
  const SceneDescription scene = parse_scene(std::string(kDevices) + R"(
[[instruments]]
name = "probe"
kind = "probe"
device = "right"
)",
                                             "scene.toml");
  const DeviceChoice c = choose_session_devices(scene);
  ASSERT_NE(c.haptic, nullptr);
  EXPECT_EQ(c.haptic->name, "right");
  ASSERT_EQ(c.hands.size(), 1u) << "only the named device is a hand";
  EXPECT_EQ(c.head->name, "head");
  // Without a binding every haptic device is a hand, in the scene's order.
  const SceneDescription unbound_scene = parse_scene(kDevices, "scene.toml");
  const DeviceChoice unbound = choose_session_devices(unbound_scene);
  ASSERT_EQ(unbound.hands.size(), 2u);
  EXPECT_EQ(unbound.hands[0]->name, "left");
  EXPECT_EQ(unbound.hands[1]->name, "right");
  EXPECT_EQ(unbound.haptic->name, "left");
}

TEST(SessionDevices, InstrumentsOnTwoDevicesMakeTwoHands) {
  const SceneDescription scene = parse_scene(std::string(kDevices) + R"(
[[instruments]]
name = "scalpel"
kind = "scalpel"
device = "right"

[[instruments]]
name = "probe"
kind = "probe"
device = "left"
)",
                                             "scene.toml");
  const DeviceChoice c = choose_session_devices(scene);
  ASSERT_EQ(c.hands.size(), 2u);
  EXPECT_EQ(c.hands[0]->name, "left") << "hands come in the scene's device order";
  EXPECT_EQ(c.hands[1]->name, "right");
}

TEST(SessionDevices, MissingRolesAndUnknownDevicesAreRefusedClearly) {
  const std::string not_haptic = error_of(std::string(kDevices) + R"(
[[instruments]]
name = "probe"
kind = "probe"
device = "head"
)");
  EXPECT_NE(not_haptic.find("instrument 'probe' names device 'head'"), std::string::npos)
      << not_haptic;
  const std::string no_head = error_of(R"(
[[devices]]
name = "left"
driver = "hid-glove"
role = "haptic"
)");
  EXPECT_NE(no_head.find("head-tracker"), std::string::npos) << no_head;
}

/// What a HID source would list on a machine with a glove and a tracker plugged in: the twins'
/// descriptors are byte for byte those of the hardware (report descriptors included).
std::vector<devices::DeviceDescriptor> plugged_in() {
  devices::SimulatedGlove glove(devices::DeviceScript{}, "GLOVE-7");
  devices::SimulatedHeadTracker head(devices::DeviceScript{}, "HEAD-3");
  std::vector<devices::DeviceDescriptor> listed{head.descriptor(), glove.descriptor()};
  for (devices::DeviceDescriptor& d : listed)
    d.kind = devices::TransportKind::Hid;
  return listed;
}

TEST(SessionDevices, RealDevicesAreFoundByDriverIdAndSerial) {
  const devices::Registry registry = devices::builtin_registry();
  const std::vector<devices::DeviceDescriptor> listed = plugged_in();
  DeviceDescription glove;
  glove.name = "glove";
  glove.driver = "hid-glove";
  glove.simulated = false;
  EXPECT_EQ(find_real_device(glove, registry, listed).serial, "GLOVE-7");
  glove.serial = "GLOVE-7";
  EXPECT_EQ(find_real_device(glove, registry, listed).driver, "hid-glove");
  // The tracker is picked for the tracker's driver, not the glove listed after it.
  DeviceDescription head = glove;
  head.name = "head";
  head.driver = "hid-tracker";
  head.serial.clear();
  EXPECT_EQ(find_real_device(head, registry, listed).serial, "HEAD-3");
}

TEST(SessionDevices, AMissingDeviceIsNamedWithWhatIsConnected) {
  const devices::Registry registry = devices::builtin_registry();
  DeviceDescription glove;
  glove.name = "glove";
  glove.driver = "hid-glove";
  glove.serial = "GLOVE-9";
  glove.simulated = false;
  try {
    (void)find_real_device(glove, registry, plugged_in());
    FAIL() << "a glove with another serial was accepted";
  } catch (const devices::DeviceError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("device 'glove' (driver hid-glove, serial GLOVE-9): not connected"),
              std::string::npos)
        << what;
    EXPECT_NE(what.find("GLOVE-7"), std::string::npos) << what;  // what is there instead
  }
  glove.driver = "no-such-driver";
  EXPECT_THROW((void)find_real_device(glove, registry, plugged_in()), SceneFileError);
}

TEST(SessionDevices, SimulatedArmAndTrackerOpenThroughTheRegistry) {
  const SceneDescription scene = parse_scene(R"(
[[devices]]
name = "arm"
driver = "vendor-arm"
role = "haptic"

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                                             "scene.toml");
  Procedure procedure;
  procedure.first_hand.motion.push_back({devices::Nanoseconds{0}, devices::Pose{}, {}});
  procedure.head.motion.push_back({devices::Nanoseconds{0}, devices::Pose{}, {}});
  devices::VirtualClock clock(devices::Nanoseconds{0});
  const devices::Registry registry = devices::builtin_registry();
  SessionDevices d(scene, procedure, registry, clock, nullptr);
  EXPECT_EQ(d.haptic().driver_name(), "vendor-arm");
  EXPECT_EQ(d.head().driver_name(), "hid-tracker");
  EXPECT_EQ(d.summary().at(0), "arm: vendor-arm (simulated)");
  // The arm's twin sends its report; the driver reads it.
  d.step_twins(devices::Nanoseconds{1'000'000});
  EXPECT_GT(d.haptic().poll(std::chrono::microseconds(0)), 0u);
  d.close();
}

/// The template driver in devices/sample/ plugs in through its registry entry alone (added here:
/// it is a template, not in the built-in registry): a scene that names it with simulated = true
/// opens its registered twin through its driver, with the channel layout the driver registered;
/// for hardware it is looked for with libusb, its registered bus.
TEST(SessionDevices, TheSampleDriverOpensFromASceneThroughItsRegistryEntry) {
  const SceneDescription scene = parse_scene(R"(
[[devices]]
name = "pinch"
driver = "sample-pinch"
role = "haptic"
serial = "PINCH-7"

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                                             "scene.toml");
  Procedure procedure;
  devices::MotionKey closed;
  closed.joints_rad = {0.4, 0.7};
  procedure.first_hand.motion.push_back(closed);
  procedure.head.motion.push_back({devices::Nanoseconds{0}, devices::Pose{}, {}});
  devices::VirtualClock clock(devices::Nanoseconds{0});
  devices::Registry registry = devices::builtin_registry();
  registry.add(devices::sample_pinch_driver_info());
  SessionDevices d(scene, procedure, registry, clock, nullptr);
  EXPECT_EQ(d.haptic().driver_name(), "sample-pinch");
  EXPECT_EQ(d.haptic().descriptor().serial, "PINCH-7");  // the scene's serial reaches the twin
  EXPECT_EQ(d.summary().at(0), "pinch: sample-pinch (simulated)");
  ASSERT_EQ(d.haptic_channels().size(), 2u);
  EXPECT_EQ(d.haptic_channels()[0], (devices::ChannelRole{devices::ChannelUse::Finger, 0}));
  EXPECT_EQ(d.haptic_channels()[1], (devices::ChannelRole{devices::ChannelUse::Finger, 1}));
  d.step_twins(devices::Nanoseconds{1'000'000});
  ASSERT_EQ(d.haptic().poll(std::chrono::microseconds(0)), 1u);
  EXPECT_NEAR(d.haptic().state().finger_joint_angles_rad[1], 0.7, 1e-4);
  d.close();
}

TEST(SessionDevices, ChannelRolesComeFromTheDriversLayout) {
  Procedure procedure;
  procedure.first_hand.motion.push_back({devices::Nanoseconds{0}, devices::Pose{}, {}});
  devices::VirtualClock clock(devices::Nanoseconds{0});
  const devices::Registry registry = devices::builtin_registry();
  const auto roles_of = [&](const std::string& driver) {
    const SceneDescription scene = parse_scene(R"(
[[devices]]
name = "hand"
driver = ")" + driver + R"("
role = "haptic"

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                                               "scene.toml");
    SessionDevices d(scene, procedure, registry, clock, nullptr);
    return d.haptic_channels();
  };
  const auto arm = roles_of("vendor-arm");
  ASSERT_EQ(arm.size(), 1u);
  EXPECT_EQ(arm[0].use, devices::ChannelUse::Vector);
  // The glove's five PID actuators take the fingers in order; its vibration channel stays unused.
  const auto glove = roles_of("hid-glove");
  ASSERT_EQ(glove.size(), 6u);
  for (std::uint8_t f = 0; f < 5; ++f)
    EXPECT_EQ(glove[f], (devices::ChannelRole{devices::ChannelUse::Finger, f}));
  EXPECT_EQ(glove[5].use, devices::ChannelUse::Unused);
}

}  // namespace
/// The headset controller's driver is on the virtual bus with no twin: the session's in-process
/// hook gives its transport (the render thread's feed); without the hook it is refused, saying
/// it has no hardware bus.
TEST(SessionDevices, TheControllerOpensThroughTheInProcessHook) {
  const SceneDescription scene = parse_scene(R"(
[[devices]]
name = "hand"
driver = "openxr-controller"
role = "haptic"
simulated = false

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                                             "scene.toml");
  Procedure procedure;
  procedure.head.motion.push_back({devices::Nanoseconds{0}, devices::Pose{}, {}});
  devices::VirtualClock clock(devices::Nanoseconds{0});
  const devices::Registry registry = devices::builtin_registry();
  try {
    SessionDevices none(scene, procedure, registry, clock, nullptr);
    ADD_FAILURE() << "opened without a feed";
  } catch (const SceneFileError& e) {
    EXPECT_NE(std::string(e.what()).find("has no hardware bus"), std::string::npos) << e.what();
  }
  devices::ControllerFeed feed;
  SessionDevices d(scene, procedure, registry, clock, nullptr,
                   [&](const devices::DriverInfo& driver) { return feed.open_for(driver); });
  EXPECT_TRUE(feed.opened());
  EXPECT_EQ(d.haptic().driver_name(), "openxr-controller");
  ASSERT_EQ(d.haptic_channels().size(), 1u);
  EXPECT_EQ(d.haptic_channels()[0], (devices::ChannelRole{devices::ChannelUse::Finger, 0}));
  devices::ControllerSample pulled;
  pulled.active = true;
  pulled.position_m = {0.01, 0.02, 0.03};
  pulled.trigger = 1.0;
  feed.push(pulled);
  ASSERT_EQ(d.haptic().poll(std::chrono::microseconds(0)), 1u);
  EXPECT_EQ(d.haptic().state().buttons, 1u);
  EXPECT_NEAR(d.haptic().state().end_effector_poses[0].position_m.z, 0.03, 1e-6);
  d.close();
  EXPECT_EQ(feed.take_vibration(), 0.0);  // closing stops the vibration
}

}  // namespace bisturi::runtime
