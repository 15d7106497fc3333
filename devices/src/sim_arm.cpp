#include <algorithm>
#include <cmath>

#include "bisturi/devices/simulated.h"
#include "bisturi/devices/vendor_arm.h"
#include "descriptor_writer.h"

namespace bisturi::devices {

namespace {

namespace ap = arm_protocol;
constexpr Nanoseconds kDeviceWatchdog = std::chrono::milliseconds(100);

DeviceDescriptor arm_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Usb;
  d.vendor_id = ap::kVendorId;
  d.product_id = ap::kProductId;
  d.serial = std::move(serial);
  d.product = "bisturi simulated haptic arm";
  d.path = "virtual:arm:" + d.serial;
  return d;
}

}  // namespace

SimulatedArm::SimulatedArm(DeviceScript script, std::string serial, double rate_hz,
                           double max_force_N, double max_force_rate_N_per_s)
    : SimulatedDevice(arm_descriptor(std::move(serial)),
                      Nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      script_(std::move(script)),
      max_force_N_(max_force_N),
      max_rate_(max_force_rate_N_per_s) {}

Vec3 SimulatedArm::applied_force_N() const {
  std::lock_guard lock(mutex_);
  return force_N_;
}
std::uint64_t SimulatedArm::force_packets() const {
  std::lock_guard lock(mutex_);
  return force_packets_;
}
std::uint64_t SimulatedArm::bad_packets() const {
  std::lock_guard lock(mutex_);
  return bad_packets_;
}

Bytes SimulatedArm::input_report(Nanoseconds t) {
  now_ = t;
  if (force_packets_ > 0 && t - last_force_time_ > kDeviceWatchdog) {
    force_N_ = {};
    watchdog_tripped_ = true;
  }
  Bytes p(ap::kPacketSize, 0);
  p[0] = ap::kState;
  p[1] = sequence_++;
  detail::put_le(p, 2, static_cast<std::uint32_t>(script_.buttons_at(t) & 0xFFFF), 2);
  const Pose pose = script_.pose_at(t);
  const double xyz[3] = {pose.position_m.x, pose.position_m.y, pose.position_m.z};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto um = static_cast<std::int32_t>(std::clamp(std::round(xyz[i] * 1e6), -2e9, 2e9));
    detail::put_le(p, 4 + 4 * i, static_cast<std::uint32_t>(um), 4);
  }
  const double q[4] = {pose.orientation.w, pose.orientation.x, pose.orientation.y,
                       pose.orientation.z};
  for (std::size_t i = 0; i < 4; ++i) {
    const auto v = static_cast<std::int16_t>(std::lround(std::clamp(q[i], -1.0, 1.0) * 16384));
    detail::put_le(p, 16 + 2 * i, static_cast<std::uint16_t>(v), 2);
  }
  const bool active = force_N_.x != 0 || force_N_.y != 0 || force_N_.z != 0;
  p[24] = static_cast<std::uint8_t>((active ? ap::kStatusForcesActive : 0) |
                                    (watchdog_tripped_ ? ap::kStatusDeviceWatchdog : 0));
  ap::seal(std::span<std::uint8_t, ap::kPacketSize>(p.data(), ap::kPacketSize));
  return p;
}

void SimulatedArm::on_output(std::span<const std::uint8_t> p) {
  if (p.size() != ap::kPacketSize || (p[30] | p[31] << 8) != ap::crc16(p.first(30))) {
    ++bad_packets_;
    return;
  }
  if (p[0] == ap::kGetInfo) {
    ap::Packet info{};
    info[0] = ap::kInfo;
    info[1] = ap::kVersion;
    const auto cN = static_cast<std::uint32_t>(std::lround(max_force_N_ * 100));
    info[2] = static_cast<std::uint8_t>(cN & 0xFF);
    info[3] = static_cast<std::uint8_t>(cN >> 8);
    const auto rate = static_cast<std::uint32_t>(std::lround(max_rate_));
    info[4] = static_cast<std::uint8_t>(rate & 0xFF);
    info[5] = static_cast<std::uint8_t>(rate >> 8);
    info[6] = 2;  // buttons
    ap::seal(info);
    send_locked(info);
  } else if (p[0] == ap::kForce) {
    double f[3];
    for (std::size_t i = 0; i < 3; ++i) {
      f[i] = static_cast<std::int16_t>(p[2 + 2 * i] | p[3 + 2 * i] << 8) / 1000.0;
    }
    // The motors saturate at the arm's limit whatever the host sends.
    const double n = std::sqrt(f[0] * f[0] + f[1] * f[1] + f[2] * f[2]);
    const double s = n > max_force_N_ ? max_force_N_ / n : 1.0;
    force_N_ = {f[0] * s, f[1] * s, f[2] * s};
    last_force_time_ = now_;
    watchdog_tripped_ = false;
    ++force_packets_;
  } else {
    ++bad_packets_;
  }
}

}  // namespace bisturi::devices
