// The device layer: HID descriptors and reports, the generic glove and tracker drivers on
// their simulated twins, the vendor arm on its twin, the force guard, hot-plug.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/hid_report.h"
#include "bisturi/devices/hotplug.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/vendor_arm.h"
#include "bisturi/devices/virtual_transport.h"

namespace bd = bisturi::devices;
namespace hid = bisturi::devices::hid;
using namespace std::chrono_literals;
using bd::Nanoseconds;

namespace {

constexpr double kDeg = std::numbers::pi / 180.0;

bd::DeviceScript glove_script() {
  bd::DeviceScript script;
  bd::MotionKey a;
  a.t = 0ms;
  a.pose.position_m = {0.10, -0.20, 0.30};
  a.joints_rad.assign(15, 0.0);
  bd::MotionKey b;
  b.t = 100ms;
  b.pose.position_m = {0.20, 0.0, 0.40};
  const double h = std::sqrt(0.5);
  b.pose.orientation = {h, 0, 0, h};  // 90 degrees about z
  b.joints_rad.assign(15, 90 * kDeg);
  script.motion = {a, b};
  script.presses = {{20ms, 0, true}, {60ms, 2, true}, {80ms, 0, false}};
  script.contacts = {{50ms, 200ms, 3, 30 * kDeg}};
  return script;
}

}  // namespace

TEST(HidDescriptor, ParsesTheRealisticGloveDescriptor) {
  const auto bytes = bd::SimulatedGlove::report_descriptor();
  const auto d = hid::parse_report_descriptor(bytes, "glove");
  EXPECT_TRUE(d.uses_report_ids);
  EXPECT_EQ(d.application_usage(), hid::kUsageGlove);
  const auto* input = d.find_report(hid::ReportType::Input, 1);
  ASSERT_NE(input, nullptr);
  EXPECT_EQ(input->bits, 304u);
  EXPECT_EQ(input->bytes(), 39u);
  const auto* forces = d.find_report(hid::ReportType::Output, 2);
  ASSERT_NE(forces, nullptr);
  EXPECT_EQ(forces->bytes(), 12u);
  ASSERT_NE(d.find_report(hid::ReportType::Output, 3), nullptr);
  // Buttons, XYZ, quaternion, flexors; effect index, magnitudes, intensity.
  ASSERT_EQ(d.fields.size(), 7u);
  const auto& buttons = d.fields[0];
  EXPECT_EQ(buttons.usages.size(), 4u);
  EXPECT_EQ(buttons.usages[0], hid::usage(hid::kPageButton, 1));
  EXPECT_EQ(buttons.bit_offset, 0u);
  const auto& xyz = d.fields[1];
  EXPECT_EQ(xyz.bit_offset, 8u);
  EXPECT_EQ(xyz.usage_of(2), hid::kUsageZ);
  EXPECT_EQ(xyz.logical_min, -32767);
  EXPECT_EQ(xyz.physical_max, 100);
  EXPECT_EQ(xyz.unit.quantity(), hid::Unit::Quantity::Length);
  EXPECT_NEAR(xyz.to_si(32767), 1.0, 1e-12);  // 100 cm
  EXPECT_TRUE(d.within(xyz.collection, hid::kUsageGlove));
  const auto& flexors = d.fields[3];
  EXPECT_EQ(flexors.bit_size, 12u);
  EXPECT_EQ(flexors.count, 15u);
  EXPECT_EQ(flexors.bit_offset, 120u);
  EXPECT_EQ(flexors.unit.quantity(), hid::Unit::Quantity::Rotation);
  EXPECT_NEAR(flexors.to_si(4095), std::numbers::pi, 1e-12);
  const auto& magnitude = d.fields[5];
  EXPECT_EQ(magnitude.usage_of(0), hid::kUsagePidMagnitude);
  EXPECT_EQ(magnitude.unit.quantity(), hid::Unit::Quantity::Force);
  EXPECT_EQ(magnitude.unit.exponent, 5);
  EXPECT_NEAR(magnitude.to_si(10000), 5.0, 1e-12);
  EXPECT_EQ(magnitude.from_si(2.5), 5000);
  EXPECT_EQ(d.fields[6].usage_of(0), hid::kUsageHapticIntensity);
}

TEST(HidDescriptor, WhatLinuxReadsIsReadWithAWarning) {
  // A Feature item before any Report Size: the global state starts at zero, no bits.
  const auto early = hid::parse_report_descriptor(
      bd::Bytes{0x95, 0x01, 0xB1, 0x02, 0x75, 0x08, 0x95, 0x01, 0x81, 0x02}, "pen");
  ASSERT_EQ(early.fields.size(), 1u);
  EXPECT_EQ(early.fields[0].type, hid::ReportType::Input);
  ASSERT_FALSE(early.warnings.empty());
  EXPECT_NE(early.warnings[0].find("byte 2: Feature: before any report size"), std::string::npos)
      << early.warnings[0];
  // Collections and no main item (a vendor interface): nothing to read, said so.
  const auto empty = hid::parse_report_descriptor(
      bd::Bytes{0x06, 0x00, 0xFF, 0x09, 0x01, 0xA1, 0x01, 0xC0}, "headset vendor interface");
  EXPECT_TRUE(empty.fields.empty());
  ASSERT_EQ(empty.warnings.size(), 1u);
  EXPECT_NE(empty.warnings[0].find("no input, output or feature fields"), std::string::npos);
  // A 32-bit unsigned range written as Logical Maximum 0xFFFFFFFF.
  const auto wide_range = hid::parse_report_descriptor(
      bd::Bytes{0x15, 0x00, 0x27, 0xFF, 0xFF, 0xFF, 0xFF, 0x75, 0x20, 0x95, 0x01, 0x81, 0x02},
      "digitiser");
  ASSERT_EQ(wide_range.fields.size(), 1u);
  EXPECT_EQ(wide_range.fields[0].logical_max, INT32_MAX);
  ASSERT_EQ(wide_range.warnings.size(), 1u);
  EXPECT_NE(wide_range.warnings[0].find("logical maximum 4294967295"), std::string::npos);
  // A usage range of 5000 (Linux takes up to 12288 usages per item).
  const auto keys = hid::parse_report_descriptor(
      bd::Bytes{0x05, 0x07, 0x19, 0x01, 0x2A, 0x88, 0x13, 0x75, 0x08, 0x95, 0x01, 0x81, 0x00},
      "keyboard");
  ASSERT_EQ(keys.fields.size(), 1u);
  EXPECT_EQ(keys.fields[0].usages.size(), 5000u);
  // Delimiters: alternative usage sets, of which the first is read.
  const auto alternatives = hid::parse_report_descriptor(
      bd::Bytes{0x05, 0x01, 0xA9, 0x01, 0x09, 0x30, 0xA9, 0x00, 0xA9, 0x01,
                0x09, 0x31, 0xA9, 0x00, 0x75, 0x08, 0x95, 0x01, 0x81, 0x02},
      "alternatives");
  ASSERT_EQ(alternatives.fields.size(), 1u);
  ASSERT_EQ(alternatives.fields[0].usages.size(), 1u);
  EXPECT_EQ(alternatives.fields[0].usages[0], 0x00010030u);
}

TEST(HidDescriptor, MalformedDescriptorsGiveProtocolErrors) {
  struct Case {
    bd::Bytes bytes;
    std::size_t offset;
    const char* reason;
  };
  const std::vector<Case> cases = {
      {{0x05, 0x01, 0x09}, 2, "data bytes"},  // truncated usage
      {{0x05, 0x01, 0xA1, 0x01, 0x75, 0x08, 0x95, 0x01, 0x81, 0x02}, 10, "not closed"},
      {{0xC0}, 0, "end collection without"},
      {{0xB4}, 0, "pop without push"},
      {{0x85, 0x00}, 0, "report id 0"},
      {{0x15, 0x0A, 0x25, 0x05, 0x75, 0x08, 0x95, 0x01, 0x81, 0x02}, 8, "below minimum"},
      {{0x0C}, 0, "reserved item type"},
      {{0x19, 0x01, 0x75, 0x08, 0x95, 0x01, 0x81, 0x00}, 6, "without maximum"},
      // Where Linux's parser stops too (hid-core.c): delimiters nested or unbalanced, a Push
      // stack deeper than its four.
      {{0xA9, 0x01, 0xA9, 0x01}, 2, "inside an open delimiter"},
      {{0xA9, 0x00}, 0, "was not open"},
      {{0xA9, 0x01}, 2, "still open"},
      {{0xA4, 0xA4, 0xA4, 0xA4, 0xA4}, 4, "deeper than 4"},
  };
  for (const auto& c : cases) {
    try {
      hid::parse_report_descriptor(c.bytes, "bad glove");
      ADD_FAILURE() << "no error for case " << c.reason;
    } catch (const bd::ProtocolError& e) {
      EXPECT_EQ(e.offset(), c.offset) << e.what();
      EXPECT_NE(std::string(e.what()).find(c.reason), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("bad glove"), std::string::npos);
    }
  }
  // A 64-bit field and a zero-size one are what shipping firmware does: warnings, not errors.
  const auto wide = hid::parse_report_descriptor(
      bd::Bytes{0x75, 0x40, 0x95, 0x01, 0x81, 0x02, 0x75, 0x00, 0x81, 0x02, 0x75, 0x08, 0x81, 0x02},
      "odd glove");
  ASSERT_EQ(wide.warnings.size(), 2u);
  EXPECT_NE(wide.warnings[0].find("byte 4: Input: 1 field(s) of 64 bits"), std::string::npos)
      << wide.warnings[0];
  EXPECT_NE(wide.warnings[1].find("byte 6: Report Size: report size 0"), std::string::npos)
      << wide.warnings[1];
  ASSERT_EQ(wide.reports.size(), 1u);
  EXPECT_EQ(wide.reports[0].bits, 72u);  // 64 + 0 + 8
  // As Linux reads them (the kernel's HID selftests have both): fields before the first Report
  // ID stay report 0, without an ID byte; a usage range past 12288 usages is cut there.
  const auto mixed = hid::parse_report_descriptor(
      bd::Bytes{0x75, 0x08, 0x95, 0x01, 0x81, 0x02, 0x85, 0x01, 0x81, 0x02}, "mixed");
  ASSERT_EQ(mixed.reports.size(), 2u);
  EXPECT_EQ(mixed.reports[0].id, 0u);
  EXPECT_FALSE(mixed.reports[0].with_id);
  EXPECT_EQ(mixed.reports[1].id, 1u);
  EXPECT_TRUE(mixed.reports[1].with_id);
  ASSERT_EQ(mixed.warnings.size(), 1u);
  EXPECT_NE(mixed.warnings[0].find("byte 6: Report ID: report id 1 after main items"),
            std::string::npos)
      << mixed.warnings[0];
  const auto huge = hid::parse_report_descriptor(
      bd::Bytes{0x05, 0x88, 0x19, 0x00, 0x2A, 0xFF, 0xFF, 0x75, 0x08, 0x95, 0x02, 0x81, 0x00},
      "ranged");
  ASSERT_EQ(huge.fields.size(), 1u);
  EXPECT_EQ(huge.fields[0].usages.size(), 12288u);
  ASSERT_EQ(huge.warnings.size(), 1u);
  EXPECT_NE(huge.warnings[0].find("usage range of 65536 usages: the first 12288 kept"),
            std::string::npos)
      << huge.warnings[0];
  ASSERT_EQ(wide.fields.size(), 1u);  // only the 8-bit one is read
  EXPECT_EQ(wide.fields[0].bit_offset, 64u);
  // Every truncation of the real descriptor either parses or gives a ProtocolError.
  const auto full = bd::SimulatedGlove::report_descriptor();
  for (std::size_t n = 0; n < full.size(); ++n) {
    try {
      hid::parse_report_descriptor(std::span(full).first(n));
    } catch (const bd::ProtocolError&) {
    }
  }
}

TEST(HidReport, BitFieldsSignedValuesAndShortReports) {
  bd::Bytes data(5, 0);
  hid::write_bits(data, 3, 12, 0xABC);
  EXPECT_EQ(hid::read_bits(data, 3, 12), 0xABCu);
  hid::write_bits(data, 7, 32, 0xDEADBEEF);
  EXPECT_EQ(hid::read_bits(data, 7, 32), 0xDEADBEEFu);
  hid::ReportCodec codec(hid::parse_report_descriptor(bd::SimulatedGlove::report_descriptor()),
                         "glove");
  auto report = codec.make_report(hid::ReportType::Input, 1);
  const auto& xyz = codec.descriptor().fields[1];
  codec.set_si(report, xyz, 1, -0.5);
  EXPECT_NEAR(codec.si(report, xyz, 1), -0.5, 1e-4);
  EXPECT_LT(codec.logical(report, xyz, 1), 0);
  const auto values = codec.decode(hid::ReportType::Input, report);
  EXPECT_EQ(values.size(), 4u + 3u + 4u + 15u);
  try {
    codec.check(hid::ReportType::Input, std::span(report).first(10));
    ADD_FAILURE();
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 10u);
    EXPECT_NE(std::string(e.what()).find("the descriptor needs 39"), std::string::npos);
  }
  report[0] = 9;
  EXPECT_THROW(codec.check(hid::ReportType::Input, report), bd::ProtocolError);
}

TEST(HidGlove, GenericDriverReadsTheSimulatedGlove) {
  bd::SimulatedGlove twin(glove_script());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto registry = bd::builtin_registry();
  auto device = registry.open(std::move(pair.host), clock);
  EXPECT_EQ(device->driver_name(), "hid-glove");
  EXPECT_EQ(device->descriptor().driver, "hid-glove");
  auto* glove = bd::as_haptic(device.get());
  ASSERT_NE(glove, nullptr);
  const auto& caps = glove->capabilities();
  EXPECT_EQ(caps.device_class, bd::DeviceClass::HapticGlove);
  EXPECT_EQ(caps.finger_joints.size(), 15u);
  EXPECT_EQ(caps.buttons, 4u);
  EXPECT_EQ(caps.end_effectors, 1u);
  ASSERT_EQ(caps.force_channels.size(), 6u);
  EXPECT_NEAR(caps.force_channels[0].max_force_N, 5.0, 1e-12);
  EXPECT_TRUE(caps.force_channels[5].unitless);

  clock.set(100ms);
  ASSERT_TRUE(twin.step(100ms));
  EXPECT_EQ(glove->poll(0us), 1u);
  const auto& s = glove->state();
  EXPECT_EQ(s.sample_time, Nanoseconds(100ms));
  EXPECT_NEAR(s.end_effector_poses[0].position_m.x, 0.20, 1e-4);
  EXPECT_NEAR(s.end_effector_poses[0].position_m.z, 0.40, 1e-4);
  EXPECT_NEAR(s.end_effector_poses[0].orientation.w, std::sqrt(0.5), 1e-4);
  EXPECT_NEAR(s.end_effector_poses[0].orientation.z, std::sqrt(0.5), 1e-4);
  EXPECT_NEAR(s.finger_joint_angles_rad[0], 90 * kDeg, 1e-3);
  EXPECT_NEAR(s.finger_joint_angles_rad[3], 30 * kDeg, 1e-3);  // contact holds joint 3
  EXPECT_EQ(s.buttons, 0b100u);                                // 0 released, 2 pressed

  ASSERT_TRUE(twin.step(101ms + 50ms));  // later, still 90 degrees
  clock.set(50ms);
  bd::SimulatedGlove early(glove_script(), "G2");
  auto pair2 = bd::make_virtual_pair(early.descriptor());
  early.attach(std::move(pair2.device));
  auto glove2 = bd::open_hid_glove(std::move(pair2.host), clock);
  early.step(50ms);
  glove2->poll(0us);
  EXPECT_NEAR(glove2->state().finger_joint_angles_rad[0], 45 * kDeg, 1e-3);
  EXPECT_NEAR(glove2->state().end_effector_poses[0].position_m.x, 0.15, 1e-4);
  EXPECT_EQ(glove2->state().buttons, 1u);

  const std::vector<double> forces = {0.0, 1.25, 2.5, 5.0, 4.0, 0.5};
  glove->send_forces(forces);
  const auto received = twin.actuator_forces_N();
  for (std::size_t i = 0; i < 5; ++i)
    EXPECT_NEAR(received[i], forces[i], 1e-3);
  EXPECT_NEAR(twin.vibration(), 0.5, 1.0 / 255);
  EXPECT_THROW(glove->send_forces(std::vector<double>(3, 0.0)), std::invalid_argument);
  // Closing sends zero forces.
  glove->close();
  for (double f : twin.actuator_forces_N())
    EXPECT_EQ(f, 0.0);
}

TEST(HidGlove, MalformedReportKeepsState) {
  bd::SimulatedGlove twin(glove_script());
  auto pair = bd::make_virtual_pair(twin.descriptor());
  auto device_side = std::move(pair.device);
  bd::VirtualClock clock;
  auto glove = bd::open_hid_glove(std::move(pair.host), clock);
  device_side->write(bd::Bytes{1, 2, 3});
  EXPECT_THROW(glove->poll(0us), bd::ProtocolError);
  EXPECT_EQ(glove->state().reports, 0u);
  EXPECT_TRUE(glove->is_open());
}

TEST(HidTracker, HeadTrackerWithoutReportIds) {
  bd::DeviceScript script;
  bd::MotionKey k;
  k.pose.position_m = {0.0123, 1.7, -0.25};
  k.pose.orientation = {std::cos(0.2), std::sin(0.2), 0, 0};
  script.motion = {k};
  bd::SimulatedHeadTracker twin(script);
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto device = bd::builtin_registry().open(std::move(pair.host), clock);
  auto* tracker = bd::as_tracker(device.get());
  ASSERT_NE(tracker, nullptr);
  EXPECT_TRUE(tracker->capabilities().head_pose);
  twin.step(0ms);
  EXPECT_EQ(tracker->poll(1ms), 1u);
  const auto& pose = tracker->state().head_pose;
  EXPECT_NEAR(pose.position_m.x, 0.0123, 1e-6);
  EXPECT_NEAR(pose.position_m.y, 1.7, 1e-6);
  EXPECT_NEAR(pose.orientation.w, std::cos(0.2), 1e-4);
  EXPECT_NEAR(pose.orientation.x, std::sin(0.2), 1e-4);
}

TEST(VendorArm, DriverAgainstItsTwin) {
  bd::DeviceScript script;
  bd::MotionKey k;
  k.pose.position_m = {0.05, -0.01, 0.12};
  script.motion = {k};
  script.presses = {{0ms, 1, true}};
  bd::SimulatedArm twin(script);
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto device = bd::builtin_registry().open(std::move(pair.host), clock);
  EXPECT_EQ(device->driver_name(), "vendor-arm");
  auto* arm = bd::as_haptic(device.get());
  ASSERT_NE(arm, nullptr);
  ASSERT_EQ(arm->capabilities().force_channels.size(), 1u);
  EXPECT_EQ(arm->capabilities().force_channels[0].components, 3);
  EXPECT_NEAR(arm->capabilities().force_channels[0].max_force_N, 8.0, 1e-9);
  EXPECT_NEAR(arm->capabilities().force_channels[0].max_force_rate_N_per_s, 400.0, 1e-9);
  EXPECT_EQ(arm->capabilities().buttons, 2u);
  twin.step(1ms);
  EXPECT_EQ(arm->poll(0us), 1u);
  EXPECT_NEAR(arm->state().end_effector_poses[0].position_m.z, 0.12, 1e-6);
  EXPECT_EQ(arm->state().buttons, 0b10u);
  const double f[3] = {1.5, -2.25, 0.001};
  arm->send_forces(f);
  EXPECT_NEAR(twin.applied_force_N().x, 1.5, 1e-9);
  EXPECT_NEAR(twin.applied_force_N().y, -2.25, 1e-9);
  EXPECT_EQ(twin.force_packets(), 1u);
  EXPECT_EQ(twin.bad_packets(), 0u);
  // The device's own watchdog: no force packet for 100 ms.
  twin.step(200ms);
  EXPECT_EQ(twin.applied_force_N().x, 0.0);
}

TEST(VendorArm, AnInfoPacketMayRateTheForcePerAxis) {
  bd::SimulatedArm twin({});
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  auto arm = bd::open_vendor_arm(std::move(pair.host));
  EXPECT_FALSE(arm->capabilities().force_channels.at(0).per_axis);  // the twin's firmware: norm
  namespace ap = bd::arm_protocol;
  ap::Packet info{};
  info[0] = ap::kInfo;
  info[1] = ap::kVersion;
  info[2] = 0x20;  // 800 cN
  info[3] = 0x03;
  info[4] = 200;  // 200 N/s
  info[6] = 1;
  info[21] = 0x01;  // per axis
  ap::seal(info);
  arm->handle_report(info);
  const bd::ForceChannel& channel = arm->capabilities().force_channels.at(0);
  EXPECT_TRUE(channel.per_axis);
  EXPECT_NEAR(channel.max_force_N, 8.0, 1e-9);
  const double diagonal[3] = {6.0, 6.0, 6.0};
  EXPECT_NEAR(bd::force_extent(channel, diagonal), 6.0, 1e-12);
}

TEST(VendorArm, CorruptPacketsAndNoAnswer) {
  bd::SimulatedArm twin({});
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  auto arm = bd::open_vendor_arm(std::move(pair.host));
  bd::Bytes bad(32, 0);
  bad[0] = 0x01;
  auto [host, device] = bd::make_virtual_pair(twin.descriptor());
  try {
    arm->handle_report(bad);
    ADD_FAILURE();
  } catch (const bd::ProtocolError& e) {
    EXPECT_EQ(e.offset(), 30u);
  }
  EXPECT_THROW(arm->handle_report(bd::Bytes(5, 0)), bd::ProtocolError);
  // Nobody answers GET_INFO.
  bd::VendorArmOptions options;
  options.info_timeout = 20ms;
  EXPECT_THROW(bd::open_vendor_arm(std::move(host), bd::steady_clock(), options), bd::DeviceError);
}

TEST(Registry, ByNameUsbIdAndDescriptor) {
  auto registry = bd::builtin_registry();
  EXPECT_NE(registry.find_by_name("hid-glove"), nullptr);
  EXPECT_EQ(registry.find_by_usb_id({0x1209, 0xB157})->name, "vendor-arm");
  bd::DeviceDescriptor unknown;
  unknown.vendor_id = 1;
  unknown.product = "mystery";
  EXPECT_EQ(registry.find(unknown), nullptr);
  auto pair = bd::make_virtual_pair(unknown);
  EXPECT_THROW(registry.open(std::move(pair.host)), bd::DeviceError);
  unknown.driver = "nope";
  auto pair2 = bd::make_virtual_pair(unknown);
  EXPECT_THROW(registry.open(std::move(pair2.host)), bd::DeviceError);
  EXPECT_THROW(registry.add(bd::hid_glove_driver_info()), std::invalid_argument);
  // Rebuilding from a recorded descriptor (as replay does): the driver name wins.
  bd::DeviceDescriptor recorded = bd::SimulatedGlove(glove_script()).descriptor();
  recorded.driver = "hid-glove";
  recorded.vendor_id = 0x1209;
  recorded.product_id = 0xB157;  // even with the arm's ids
  EXPECT_EQ(registry.find(recorded)->name, "hid-glove");
}

namespace {

bd::ForceChannel finger(double max_N = 5.0, double rate = 100.0) {
  return bd::ForceChannel{"finger", 1, max_N, rate, false};
}

}  // namespace

TEST(ForceGuard, WaitsForASmallCommandThenRampsIn) {
  bd::ForceGuardConfig config;
  config.ramp_in = 100ms;
  bd::ForceGuard guard({finger(5.0, 1000.0)}, config);
  double out = -1;
  double cmd = 3.0;
  Nanoseconds t = 0ms;
  auto step = [&](double c) {
    cmd = c;
    t += 1ms;
    guard.device_answered(t);
    return guard.step(std::span(&cmd, 1), t, std::span(&out, 1));
  };
  EXPECT_EQ(step(3.0).state, bd::GuardState::WaitingForSmallCommand);
  EXPECT_EQ(out, 0.0);
  EXPECT_EQ(step(0.05).state, bd::GuardState::RampingIn);
  for (int i = 0; i < 49; ++i)
    step(2.0);
  EXPECT_NEAR(out, 1.0, 0.05);  // half way through the ramp
  for (int i = 0; i < 60; ++i)
    step(2.0);
  EXPECT_EQ(guard.state(), bd::GuardState::Engaged);
  EXPECT_NEAR(out, 2.0, 1e-12);
}

TEST(ForceGuard, ClampsAndLimitsTheRate) {
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceGuard guard({finger(5.0, 100.0), bd::ForceChannel{"tip", 3, 2.0, 1000.0, false}},
                       config);
  double cmd[4] = {0, 0, 0, 0}, out[4];
  guard.step(cmd, 1ms, out);
  EXPECT_EQ(guard.state(), bd::GuardState::Engaged);
  double big[4] = {50, 3, 4, 0};  // 50 N finger, 5 N vector
  auto r = guard.step(big, 2ms, out);
  EXPECT_TRUE(r.clamped);
  EXPECT_TRUE(r.rate_limited);
  EXPECT_NEAR(out[0], 0.1, 1e-12);                      // 100 N/s for 1 ms
  EXPECT_NEAR(std::hypot(out[1], out[2]), 1.0, 1e-12);  // 1000 N/s for 1 ms
  Nanoseconds t = 2ms;
  for (int i = 0; i < 100; ++i) {
    guard.device_answered(t += 1ms);
    guard.step(big, t, out);
  }
  EXPECT_NEAR(out[0], 5.0, 1e-12);
  EXPECT_NEAR(out[1], 2.0 * 3 / 5, 1e-12);
  EXPECT_NEAR(out[2], 2.0 * 4 / 5, 1e-12);
  EXPECT_GT(guard.clamp_count(), 0u);
}

TEST(ForceGuard, APerAxisLimitKeepsTheDiagonalAndTheDirection) {
  // A channel rated 8 N per axis: 6 N along each axis at once (10.4 N in all) passes whole; a
  // force with a component over 8 N is scaled down whole by that component, not clipped per axis.
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceChannel tip{"tip", 3, 8.0, 1e6, false};
  tip.per_axis = true;
  bd::ForceGuard guard({tip}, config);
  double zero[3] = {0, 0, 0}, out[3];
  guard.step(zero, 1ms, out);
  double diagonal[3] = {6.0, -6.0, 6.0};
  EXPECT_FALSE(guard.step(diagonal, 2ms, out).clamped);
  EXPECT_EQ(out[0], 6.0);
  EXPECT_EQ(out[1], -6.0);
  EXPECT_EQ(out[2], 6.0);
  double over[3] = {10.0, 4.0, 0.0};
  EXPECT_TRUE(guard.step(over, 3ms, out).clamped);
  EXPECT_NEAR(out[0], 8.0, 1e-12);
  EXPECT_NEAR(out[1], 3.2, 1e-12);  // 4 x 8/10: the direction kept
  EXPECT_EQ(out[2], 0.0);
}

TEST(ForceGuard, ACommandAtTheLimitCountsAsClamped) {
  // The session clamps its commands to the scene's limit before the guard sees them: they
  // arrive exactly at the limit, and the report must still count them.
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceGuard guard({finger(3.0, 1e6)}, config);
  double cmd = 0.0, out = 0.0;
  guard.step(std::span(&cmd, 1), 1ms, std::span(&out, 1));
  cmd = 2.999;
  EXPECT_FALSE(guard.step(std::span(&cmd, 1), 2ms, std::span(&out, 1)).clamped);
  cmd = 3.0;
  EXPECT_TRUE(guard.step(std::span(&cmd, 1), 3ms, std::span(&out, 1)).clamped);
  EXPECT_EQ(out, 3.0);
  EXPECT_EQ(guard.clamp_count(), 1u);
}

TEST(ForceGuard, NanLatchesUntilRearm) {
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceGuard guard({finger()}, config);
  double out = 0, cmd = 0;
  guard.step(std::span(&cmd, 1), 1ms, std::span(&out, 1));
  cmd = 1;
  for (int i = 2; i < 30; ++i)
    guard.step(std::span(&cmd, 1), Nanoseconds(i * 1000000), std::span(&out, 1));
  EXPECT_GT(out, 0.5);
  cmd = std::nan("");
  auto r = guard.step(std::span(&cmd, 1), 30ms, std::span(&out, 1));
  EXPECT_EQ(r.latched, bd::Fault::NonFiniteCommand);
  EXPECT_EQ(out, 0.0);
  cmd = 0;
  guard.step(std::span(&cmd, 1), 31ms, std::span(&out, 1));
  EXPECT_EQ(guard.state(), bd::GuardState::Latched);
  EXPECT_EQ(out, 0.0);
  guard.rearm();
  guard.step(std::span(&cmd, 1), 40ms, std::span(&out, 1));
  EXPECT_EQ(guard.state(), bd::GuardState::Engaged);
}

TEST(ForceGuard, WatchdogDeadlineAndSilence) {
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceGuard guard({finger()}, config);
  double out = 0, cmd = 0;
  Nanoseconds t = 0ms;
  auto step = [&](Nanoseconds dt, bool answer = true) {
    t += dt;
    if (answer) guard.device_answered(t);
    return guard.step(std::span(&cmd, 1), t, std::span(&out, 1));
  };
  step(1ms);
  cmd = 1;
  for (int i = 0; i < 20; ++i)
    step(1ms);
  EXPECT_GT(out, 0.5);
  // 2.9 ms late is within period (1) + margin (2); 3.1 ms is not.
  EXPECT_EQ(step(2900us).latched, bd::Fault::None);
  EXPECT_EQ(step(3100us).latched, bd::Fault::DeadlineOverrun);
  EXPECT_EQ(out, 0.0);
  // Back on time: re-arms by itself but waits for a small command again.
  step(1ms);
  EXPECT_EQ(guard.state(), bd::GuardState::WaitingForSmallCommand);
  EXPECT_EQ(out, 0.0);
  cmd = 0;
  step(1ms);
  cmd = 1;
  for (int i = 0; i < 20; ++i)
    step(1ms);
  EXPECT_GT(out, 0.5);
  // The device stops answering: zero after the silence timeout.
  bd::GuardStep r;
  for (int i = 0; i < 60 && r.latched == bd::Fault::None; ++i)
    r = step(1ms, false);
  EXPECT_EQ(r.latched, bd::Fault::DeviceSilent);
  EXPECT_EQ(out, 0.0);
  bd::ForceGuard fresh({finger()}, config);
  fresh.device_answered(0ms);
  fresh.step(std::span(&cmd, 1), 0ms, std::span(&out, 1));
  EXPECT_FALSE(fresh.watchdog_expired(2ms));  // no step missed yet...
  EXPECT_TRUE(fresh.watchdog_expired(4ms));   // ...now it is late
  EXPECT_EQ(fresh.latch_reason(), bd::Fault::DeadlineOverrun);
}

TEST(ForceGuard, DisconnectZeroesFirst) {
  bd::SimulatedArm twin({});
  auto pair = bd::make_virtual_pair(twin.descriptor());
  twin.attach(std::move(pair.device));
  bd::VirtualClock clock;
  auto arm = bd::open_vendor_arm(std::move(pair.host), clock);
  bd::ForceGuardConfig config;
  config.ramp_in = 0ms;
  bd::ForceGuard guard(arm->capabilities().force_channels, config);
  double cmd[3] = {0, 0, 0}, out[3];
  for (int i = 1; i < 100; ++i) {
    clock.set(Nanoseconds(i * 1000000));
    twin.step(clock.now());
    arm->poll(0us);
    guard.device_answered(clock.now());
    cmd[0] = i == 1 ? 0.0 : 2.0;
    guard.step(cmd, clock.now(), out);
    arm->send_forces(out);
  }
  EXPECT_NEAR(twin.applied_force_N().x, 2.0, 1e-3);
  // A lost device: latch, send the zeros, then drop the device.
  guard.device_disconnected();
  EXPECT_EQ(guard.last_output()[0], 0.0);
  arm->send_forces(guard.last_output());
  EXPECT_EQ(twin.applied_force_N().x, 0.0);
  guard.step(cmd, clock.now() + 1ms, out);
  EXPECT_EQ(out[0], 0.0);
  EXPECT_EQ(guard.latch_reason(), bd::Fault::DeviceDisconnected);
}

TEST(Hotplug, DisconnectAndReconnectMidSession) {
  bd::VirtualClock clock;
  bd::VirtualBus bus;
  bd::SimulatedGlove glove(glove_script());
  bd::SimulatedArm arm({});
  bus.plug(glove.descriptor(), glove.connector());
  auto registry = bd::builtin_registry();
  bd::DeviceManager manager(registry, clock);
  manager.add_source(bus);
  auto events = manager.scan();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, bd::DeviceEventKind::Arrived);
  EXPECT_EQ(events[1].kind, bd::DeviceEventKind::Opened);
  EXPECT_EQ(events[1].device.driver, "hid-glove");
  bus.plug(arm.descriptor(), arm.connector());
  events = manager.scan();
  ASSERT_EQ(events.size(), 2u);
  ASSERT_EQ(manager.devices().size(), 2u);
  EXPECT_TRUE(manager.scan().empty());

  auto* g = bd::as_haptic(manager.find(glove.descriptor().path));
  ASSERT_NE(g, nullptr);
  glove.step(10ms);
  EXPECT_EQ(g->poll(0us), 1u);
  // Unplug mid-session: the driver sees DeviceDisconnected, the session goes on with the arm.
  bus.unplug(glove.descriptor().path);
  EXPECT_THROW(g->poll(0us), bd::DeviceDisconnected);
  EXPECT_FALSE(g->is_open());
  events = manager.scan();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, bd::DeviceEventKind::Disconnected);
  EXPECT_EQ(events[1].kind, bd::DeviceEventKind::Removed);
  EXPECT_EQ(manager.devices().size(), 1u);
  // Plug back: picked up again.
  bus.plug(glove.descriptor(), glove.connector());
  events = manager.scan();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[1].kind, bd::DeviceEventKind::Reconnected);
  g = bd::as_haptic(manager.find(glove.descriptor().path));
  ASSERT_NE(g, nullptr);
  glove.step(20ms);
  EXPECT_EQ(g->poll(0us), 1u);
  // A link that breaks while still listed is reopened on the next scan.
  glove.disconnect();
  EXPECT_THROW(g->poll(0us), bd::DeviceDisconnected);
  events = manager.scan();
  ASSERT_EQ(events.size(), 2u);
  EXPECT_EQ(events[0].kind, bd::DeviceEventKind::Disconnected);
  EXPECT_EQ(events[1].kind, bd::DeviceEventKind::Reconnected);
}

TEST(VirtualTransport, QueuesTimeoutsAndThreads) {
  auto pair = bd::make_virtual_pair({}, 2);
  EXPECT_FALSE(pair.host->read(1ms).has_value());
  pair.device->write(bd::Bytes{1});
  pair.device->write(bd::Bytes{2});
  pair.device->write(bd::Bytes{3});
  EXPECT_EQ(pair.host->dropped(), 1u);
  EXPECT_EQ((*pair.host->read(0us))[0], 2);
  std::thread writer([&] {
    std::this_thread::sleep_for(5ms);
    pair.device->write(bd::Bytes{9});
  });
  EXPECT_EQ((*pair.host->read(0us))[0], 3);
  auto r = pair.host->read(2s);
  writer.join();
  ASSERT_TRUE(r.has_value());
  EXPECT_EQ((*r)[0], 9);
  pair.device->disconnect();
  EXPECT_THROW(pair.host->read(0us), bd::DeviceDisconnected);
  EXPECT_THROW(pair.host->write(bd::Bytes{1}), bd::DeviceDisconnected);
}

TEST(VirtualTransport, APreemptingWriteOvertakesAStuckWrite) {
  auto pair = bd::make_virtual_pair({});
  pair.host->write(bd::Bytes{1});
  // The device holds off: the host's next write is stuck for 300 ms.
  pair.device->stall_next_host_write(300ms);
  std::atomic<bool> returned{false};
  std::thread stuck([&] {
    pair.host->write(bd::Bytes{2});
    returned.store(true);
  });
  std::this_thread::sleep_for(20ms);
  ASSERT_FALSE(returned.load());
  // From another thread, past the stuck write and ahead of the queue; only host to device.
  EXPECT_TRUE(pair.host->write_preempting(bd::Bytes{0, 0}));
  EXPECT_FALSE(pair.device->write_preempting(bd::Bytes{7}));
  auto first = pair.device->read(0us);
  ASSERT_TRUE(first.has_value());
  EXPECT_EQ(*first, (bd::Bytes{0, 0}));
  EXPECT_FALSE(returned.load()) << "the zero did not wait for the stuck write";
  EXPECT_EQ((*pair.device->read(0us))[0], 1);
  stuck.join();
  EXPECT_EQ((*pair.device->read(0us))[0], 2);
  // Four slots of 64 bytes: a fifth waiting report, or a longer one, is refused.
  for (int i = 0; i < 4; ++i)
    EXPECT_TRUE(pair.host->write_preempting(bd::Bytes{static_cast<std::uint8_t>(i)}));
  EXPECT_FALSE(pair.host->write_preempting(bd::Bytes{9}));
  for (int i = 0; i < 4; ++i)
    EXPECT_EQ((*pair.device->read(0us))[0], i) << "in the order written";
  EXPECT_FALSE(pair.host->write_preempting(bd::Bytes(65, 0)));
}

TEST(Device, TheHidGloveAndTheArmZeroPastAStuckWrite) {
  // Each driver's preempting zero reaches its twin (which takes it as soon as it is written)
  // and turns off every force the host had set.
  bd::VirtualClock clock;
  bd::SimulatedGlove glove(bd::DeviceScript{}, "GLOVE-1", 1000.0);
  bd::SimulatedArm arm(bd::DeviceScript{}, "ARM-1", 1000.0);
  for (bd::SimulatedDevice* twin :
       {static_cast<bd::SimulatedDevice*>(&glove), static_cast<bd::SimulatedDevice*>(&arm)}) {
    auto pair = bd::make_virtual_pair(twin->descriptor());
    twin->attach(std::move(pair.device));
    std::unique_ptr<bd::Device> device = bd::builtin_registry().open(std::move(pair.host), clock);
    bd::HapticDevice* haptic = bd::as_haptic(device.get());
    ASSERT_NE(haptic, nullptr);
    const std::vector<double> forces(haptic->capabilities().force_components(), 0.5);
    haptic->send_forces(forces);
    const auto felt = [&] {
      if (twin == &arm) {
        const bd::Vec3 f = arm.applied_force_N();
        return std::abs(f.x) + std::abs(f.y) + std::abs(f.z);
      }
      double sum = 0.0;
      for (const double f : glove.actuator_forces_N())
        sum += std::abs(f);
      return sum;
    };
    ASSERT_GT(felt(), 0.1) << device->driver_name();
    EXPECT_FALSE(device->send_zero_preempting()) << "not prepared yet";
    device->prepare_preempting_zero();
    ASSERT_TRUE(device->send_zero_preempting()) << device->driver_name();
    EXPECT_EQ(felt(), 0.0) << device->driver_name();
    device->close();
  }
}
