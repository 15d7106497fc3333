// The openxr-controller driver and its feed: report decoding, trigger to button, the vibration
// amplitude from the guarded force, zero when the guard latches.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bisturi/devices/controller/openxr_controller.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"

namespace bisturi::devices {
namespace {

namespace cp = controller_protocol;

ControllerSample sample(double trigger, double x = 0.1) {
  ControllerSample s;
  s.t_ns = 123456789012345;
  s.active = true;
  s.position_m = {x, -0.2, -0.45};
  const double h = std::sqrt(0.5);
  s.orientation = {h, 0.0, h, 0.0};  // w, x, y, z: 90 degrees about y
  s.trigger = trigger;
  return s;
}

struct Rig {
  ControllerFeed feed;
  std::unique_ptr<HapticDevice> device;
  Rig() { device = open_openxr_controller(feed.open(), steady_clock()); }
};

TEST(OpenXrController, DecodesPoseAndTriggerFromTheFeed) {
  Rig rig;
  rig.feed.push(sample(0.2));
  EXPECT_EQ(rig.device->poll(std::chrono::microseconds(1000)), 1u);
  const HapticState& s = rig.device->state();
  ASSERT_EQ(s.end_effector_poses.size(), 1u);
  EXPECT_NEAR(s.end_effector_poses[0].position_m.x, 0.1, 1e-6);
  EXPECT_NEAR(s.end_effector_poses[0].position_m.z, -0.45, 1e-6);
  EXPECT_NEAR(s.end_effector_poses[0].orientation.w, std::sqrt(0.5), 1e-6);
  EXPECT_NEAR(s.end_effector_poses[0].orientation.y, std::sqrt(0.5), 1e-6);
  EXPECT_EQ(s.buttons, 0u);
  rig.feed.push(sample(0.8));
  rig.device->poll(std::chrono::microseconds(1000));
  EXPECT_EQ(s.buttons, 1u);  // trigger > 0.5 grasps
  EXPECT_EQ(s.reports, 2u);
}

TEST(OpenXrController, InactiveKeepsTheLastPose) {
  Rig rig;
  rig.feed.push(sample(0.0, 0.1));
  ControllerSample lost = sample(0.9, 0.7);
  lost.active = false;
  rig.feed.push(lost);
  rig.device->poll(std::chrono::microseconds(1000));
  EXPECT_NEAR(rig.device->state().end_effector_poses[0].position_m.x, 0.1, 1e-6);
  EXPECT_EQ(rig.device->state().buttons, 1u);
}

TEST(OpenXrController, RejectsMalformedReports) {
  Rig rig;
  Bytes good = encode_controller_report(sample(0.3));
  Bytes shortr(good.begin(), good.end() - 1);
  EXPECT_THROW(rig.device->handle_report(shortr), ProtocolError);
  Bytes type = good;
  type[0] = 0x07;
  EXPECT_THROW(rig.device->handle_report(type), ProtocolError);
  Bytes flags = good;
  flags[1] = 0x81;
  EXPECT_THROW(rig.device->handle_report(flags), ProtocolError);
  ControllerSample bad_q = sample(0.3);
  bad_q.orientation = {1.0, 0.5, 0.0, 0.0};
  EXPECT_THROW(rig.device->handle_report(encode_controller_report(bad_q)), ProtocolError);
  Bytes nan = good;
  const auto bits = std::bit_cast<std::uint32_t>(std::numeric_limits<float>::quiet_NaN());
  for (int i = 0; i < 4; ++i)
    nan[12 + static_cast<std::size_t>(i)] = static_cast<std::uint8_t>(bits >> (8 * i));
  EXPECT_THROW(rig.device->handle_report(nan), ProtocolError);
  EXPECT_EQ(rig.device->state().reports, 0u);  // none changed the state
  rig.device->handle_report(good);
  EXPECT_EQ(rig.device->state().reports, 1u);
}

TEST(OpenXrController, AmplitudeIsTheForceOverItsLimit) {
  Rig rig;
  const double one[1] = {1.0};
  rig.device->send_forces(one);
  EXPECT_NEAR(*rig.feed.take_vibration(), 1.0 / cp::kMaxForceN, 1e-6);
  const double over[1] = {-3.0 * cp::kMaxForceN};  // a pull either way is its magnitude
  rig.device->send_forces(over);
  EXPECT_FLOAT_EQ(static_cast<float>(*rig.feed.take_vibration()), 1.0f);
  EXPECT_FALSE(rig.feed.take_vibration());  // taken: nothing new
  const double two[2] = {1.0, 1.0};
  EXPECT_THROW(rig.device->send_forces(two), std::invalid_argument);
  EXPECT_EQ(rig.feed.rejected(), 0u);
}

TEST(OpenXrController, GuardLatchGivesZeroAmplitude) {
  Rig rig;
  ForceGuardConfig config;
  config.ramp_in = Nanoseconds(0);
  ForceGuard guard(rig.device->capabilities().force_channels, config);
  double out[1] = {0.0};
  Nanoseconds t{0};
  const double small[1] = {0.0};
  for (int i = 0; i < 3; ++i) {
    t += std::chrono::milliseconds(1);
    guard.device_answered(t);
    guard.step(small, t, out);
  }
  const double two[1] = {2.0};
  t += std::chrono::milliseconds(1);
  guard.device_answered(t);
  guard.step(two, t, out);
  rig.device->send_forces(out);
  const std::optional<double> engaged = rig.feed.take_vibration();
  ASSERT_TRUE(engaged);
  EXPECT_GT(*engaged, 0.0);
  const double nan[1] = {std::numeric_limits<double>::quiet_NaN()};
  t += std::chrono::milliseconds(1);
  guard.device_answered(t);
  guard.step(nan, t, out);
  EXPECT_EQ(guard.state(), GuardState::Latched);
  rig.device->send_forces(out);
  EXPECT_EQ(*rig.feed.take_vibration(), 0.0);
  t += std::chrono::milliseconds(1);
  guard.step(two, t, out);  // latched: still zero
  rig.device->send_forces(out);
  EXPECT_EQ(*rig.feed.take_vibration(), 0.0);
}

TEST(OpenXrController, CloseSendsZeroAndTheFeedOpensOnce) {
  Rig rig;
  EXPECT_EQ(rig.feed.open(), nullptr);
  const double one[1] = {2.0};
  rig.device->send_forces(one);
  rig.device->close();
  EXPECT_EQ(*rig.feed.take_vibration(), 0.0);  // the newest: close's zero
}

TEST(OpenXrController, RegisteredOnTheVirtualBus) {
  const Registry registry = builtin_registry();
  const DriverInfo* info = registry.find_by_name(kOpenXrControllerDriver);
  ASSERT_NE(info, nullptr);
  EXPECT_EQ(info->bus, TransportKind::Virtual);
  EXPECT_FALSE(info->make_twin);
  ControllerFeed feed;
  std::unique_ptr<Device> d = registry.open(feed.open());  // by the descriptor's driver name
  EXPECT_EQ(d->driver_name(), kOpenXrControllerDriver);
  ASSERT_NE(as_haptic(d.get()), nullptr);
  const std::vector<ChannelRole> roles = info->layout.roles(d->capabilities());
  ASSERT_EQ(roles.size(), 1u);
  EXPECT_EQ(roles[0].use, ChannelUse::Finger);
}

}  // namespace
}  // namespace bisturi::devices
