// `bisturi device check` underneath (runtime/session/device_check.h): a driver against its twin
// through the guard and the haptic loop, as a session would use it.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <stdexcept>
#include <string>
#include <vector>

#include "bisturi/devices/registry.h"
#include "bisturi/devices/sample/sample_arm.h"
#include "bisturi/runtime/session/device_check.h"

namespace bisturi::runtime {
namespace {

std::vector<std::string> kinds(const DeviceCheckResult& r) {
  std::vector<std::string> out;
  for (const SessionEvent& e : r.events)
    out.emplace_back(to_string(e.kind));
  return out;
}

/// The events but new touches: a graze of the default scene's pulsing artery can count as one
/// touch or two (the count debounces 100 ticks), and a turned run's did once.
std::vector<std::string> actions(const DeviceCheckResult& r) {
  std::vector<std::string> out;
  for (const SessionEvent& e : r.events)
    if (e.kind != SessionEventKind::Contact) out.emplace_back(to_string(e.kind));
  return out;
}

bool has(const std::vector<std::string>& v, const std::string& s) {
  return std::find(v.begin(), v.end(), s) != v.end();
}

TEST(DeviceCheck, TheArmGraspsWithItsGripCutsAndIsHeldToTheScenesLimit) {
  DeviceCheckOptions options;
  options.driver = "vendor-arm";
  options.seconds = 3.0;
  options.max_force_N = 2.0;
  const DeviceCheckResult r = check_device(options, devices::builtin_registry());
  EXPECT_EQ(r.ticks, 3000u);
  const std::vector<std::string> done = kinds(r);
  EXPECT_TRUE(has(done, "contact"));
  EXPECT_TRUE(has(done, "grasp")) << "button 0 grasps";
  EXPECT_TRUE(has(done, "cut")) << "button 1 cuts";
  ASSERT_EQ(r.channels.size(), 1u);
  EXPECT_EQ(r.channels[0].role, "vector");
  EXPECT_DOUBLE_EQ(r.channels[0].limit_N, 2.0);
  EXPECT_LE(r.channels[0].peak_output_N, 2.0 + 1e-9) << "never above the limit";
  EXPECT_GT(r.channels[0].peak_output_N, 0.5);
  ASSERT_EQ(r.buttons.size(), 2u);
  EXPECT_EQ(r.buttons[0], "grasp");
  EXPECT_EQ(r.guard_latches, 0u);
  EXPECT_EQ(r.malformed_reports, 0u);
  EXPECT_TRUE(r.warnings.empty());
  EXPECT_FALSE(r.samples.empty());
}

TEST(DeviceCheck, ATurnedDeviceDoesWhatAStraightOneDoes) {
  // The twin follows the script through the inverse of the device's placement: the instrument
  // does the same in the scene, and the same force reaches the hand (in the device's frame).
  DeviceCheckOptions options;
  options.driver = "vendor-arm";
  options.seconds = 2.0;
  const DeviceCheckResult straight = check_device(options, devices::builtin_registry());
  options.rotation_deg = {0.0, 0.0, 90.0};
  options.translation_mm = {10.0, -5.0, 0.0};
  const DeviceCheckResult turned = check_device(options, devices::builtin_registry());
  EXPECT_EQ(actions(straight), actions(turned));
  EXPECT_TRUE(has(kinds(turned), "contact"));
  EXPECT_NEAR(turned.channels[0].peak_output_N, straight.channels[0].peak_output_N,
              0.02 * straight.channels[0].peak_output_N + 1e-3);
  ASSERT_EQ(straight.samples.size(), turned.samples.size());
  for (std::size_t i = 0; i < straight.samples.size(); ++i)
    EXPECT_NEAR(glm::length(straight.samples[i].tip_mm - turned.samples[i].tip_mm), 0.0, 1e-6);
}

TEST(DeviceCheck, TheArmTemplateGraspsCutsAndKeepsItsAxisRating) {
  // devices/sample's arm, added to a registry of the test's own as an integrator's program adds
  // its driver: its grip grasps, its thumb button cuts, and its force stays within 8 N per axis.
  devices::Registry registry = devices::builtin_registry();
  registry.add(devices::sample_arm_driver_info());
  DeviceCheckOptions options;
  options.driver = devices::kSampleArmDriver;
  options.seconds = 3.0;
  options.max_force_N = 20.0;  // above the arm's own rating: the device's limit holds
  const DeviceCheckResult r = check_device(options, registry);
  const std::vector<std::string> done = kinds(r);
  EXPECT_TRUE(has(done, "grasp"));
  EXPECT_TRUE(has(done, "cut"));
  ASSERT_EQ(r.channels.size(), 1u);
  EXPECT_TRUE(r.channels[0].per_axis);
  EXPECT_DOUBLE_EQ(r.channels[0].limit_N, 8.0);
  EXPECT_LE(r.channels[0].peak_output_N, 8.0 + 1e-9);
  EXPECT_EQ(r.buttons, (std::vector<std::string>{"grasp", "cut", "clutch"}));
  EXPECT_TRUE(r.warnings.empty());
}

TEST(DeviceCheck, DriversItCannotCheckAreNamed) {
  DeviceCheckOptions options;
  options.driver = "no-such-driver";
  try {
    (void)check_device(options, devices::builtin_registry());
    FAIL() << "an unknown driver ran";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("vendor-arm"), std::string::npos) << e.what();
  }
  options.driver = "openxr-controller";
  EXPECT_THROW((void)check_device(options, devices::builtin_registry()), std::invalid_argument);
  options.driver = "hid-tracker";
  EXPECT_THROW((void)check_device(options, devices::builtin_registry()), std::invalid_argument);
}

}  // namespace
}  // namespace bisturi::runtime
