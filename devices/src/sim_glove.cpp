#include <algorithm>
#include <cmath>
#include <numbers>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/hid_report.h"
#include "bisturi/devices/simulated.h"
#include "descriptor_writer.h"

namespace bisturi::devices {

namespace {

// Input report 1 (39 bytes with the id): buttons 4 bits + 4 padding, X Y Z int16 (-100..100 cm),
// quaternion x y z w int16 (-1..1), 15 flexors 12 bits (0..180 degrees), 4 bits padding.
// Output report 2 (12 bytes): effect block index, 5 magnitudes uint16 (0..5 N).
// Output report 3 (2 bytes): vibration intensity 0..255.
constexpr std::uint32_t kButtonsBit = 8, kPositionBit = 16, kQuaternionBit = 64, kFlexorBit = 128;
constexpr std::size_t kInputBytes = 39;
constexpr double kDegree = std::numbers::pi / 180.0;

std::int32_t to_logical(double v, double v_min, double v_max, std::int32_t l_min,
                        std::int32_t l_max) {
  const double s = (std::clamp(v, v_min, v_max) - v_min) / (v_max - v_min);
  return static_cast<std::int32_t>(std::lround(l_min + s * (static_cast<double>(l_max) - l_min)));
}

DeviceDescriptor glove_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Hid;
  d.vendor_id = 0x1209;
  d.product_id = 0xB150;
  d.serial = std::move(serial);
  d.product = "bisturi simulated glove";
  d.path = "virtual:glove:" + d.serial;
  d.report_descriptor = SimulatedGlove::report_descriptor();
  return d;
}

}  // namespace

Bytes SimulatedGlove::report_descriptor() {
  detail::DescriptorWriter w;
  w.usage_page(hid::kPageVrControls).usage(0x04).collection(1);  // Glove, application
  w.report(1);
  w.usage_page(hid::kPageButton).usage_range(1, 4).logical(0, 1).size_count(1, 4).input(0x02);
  w.size_count(4, 1).input(0x01);
  w.usage_page(hid::kPageGenericDesktop).usage(0x01).collection(0);  // Pointer, physical
  w.usage(0x30).usage(0x31).usage(0x32).logical(-32767, 32767).physical(-100, 100);
  w.unit(0x11, 0).size_count(16, 3).input(0x02);  // centimetres
  w.usage_page(hid::kPageSensors).usage(0x0483).logical(-16384, 16384).physical(-1, 1);
  w.unit(0, 0).size_count(16, 4).input(0x02);
  w.end_collection();
  w.usage_page(hid::kPageVrControls).usage(0x03).logical(0, 4095).physical(0, 180);
  w.unit(0x14, 0).size_count(12, static_cast<std::uint32_t>(kJoints)).input(0x02);  // degrees
  w.unit(0, 0).size_count(4, 1).input(0x01);
  w.report(2);
  w.usage_page(hid::kPagePid).usage(0x73).collection(2);  // Set Constant Force Report, logical
  w.usage(0x22).logical(1, 40).physical(0, 0).size_count(8, 1).output(0x02);
  w.usage(0x70).logical(0, 10000).physical(0, 5).unit(0xE111, 5);  // newtons (10^5 dyne)
  w.size_count(16, static_cast<std::uint32_t>(kActuators)).output(0x02);
  w.end_collection();
  w.report(3);
  w.usage_page(hid::kPageHaptics).usage(0x23).logical(0, 255).physical(0, 0).unit(0, 0);
  w.size_count(8, 1).output(0x02);
  w.end_collection();
  return w.take();
}

SimulatedGlove::SimulatedGlove(DeviceScript script, std::string serial, double rate_hz)
    : SimulatedDevice(glove_descriptor(std::move(serial)),
                      Nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      script_(std::move(script)),
      forces_N_(kActuators, 0.0) {}

std::vector<double> SimulatedGlove::actuator_forces_N() const {
  std::lock_guard lock(mutex_);
  return forces_N_;
}

double SimulatedGlove::vibration() const {
  std::lock_guard lock(mutex_);
  return vibration_;
}

Bytes SimulatedGlove::input_report(Nanoseconds t) {
  Bytes report(kInputBytes, 0);
  report[0] = 1;
  const Pose pose = script_.pose_at(t);
  const auto joints = script_.joints_at(t, kJoints);
  hid::write_bits(report, kButtonsBit, 4, static_cast<std::uint32_t>(script_.buttons_at(t) & 0xF));
  const double position_cm[3] = {pose.position_m.x * 100, pose.position_m.y * 100,
                                 pose.position_m.z * 100};
  for (std::uint32_t i = 0; i < 3; ++i) {
    hid::write_bits(
        report, kPositionBit + 16 * i, 16,
        static_cast<std::uint32_t>(to_logical(position_cm[i], -100, 100, -32767, 32767)));
  }
  const double q[4] = {pose.orientation.x, pose.orientation.y, pose.orientation.z,
                       pose.orientation.w};
  for (std::uint32_t i = 0; i < 4; ++i) {
    hid::write_bits(report, kQuaternionBit + 16 * i, 16,
                    static_cast<std::uint32_t>(to_logical(q[i], -1, 1, -16384, 16384)));
  }
  for (std::uint32_t j = 0; j < kJoints; ++j) {
    hid::write_bits(report, kFlexorBit + 12 * j, 12,
                    static_cast<std::uint32_t>(to_logical(joints[j] / kDegree, 0, 180, 0, 4095)));
  }
  return report;
}

void SimulatedGlove::on_output(std::span<const std::uint8_t> report) {
  if (report.size() >= 12 && report[0] == 2) {
    for (std::uint32_t i = 0; i < kActuators; ++i) {
      const auto logical = hid::read_bits(report, 16 + 16 * i, 16);
      forces_N_[i] = std::min<double>(logical, 10000) * 5.0 / 10000.0;
    }
  } else if (report.size() >= 2 && report[0] == 3) {
    vibration_ = report[1] / 255.0;
  }
}

}  // namespace bisturi::devices
