// The sample arm's twin. It writes and checks its bytes with code of its own, from the protocol
// in sample_arm.h, never with the driver's: a mistake on one side cannot hide behind the same
// mistake on the other.
#include <cmath>

#include "bisturi/devices/sample/sample_arm.h"

namespace bisturi::devices {

namespace {

DeviceDescriptor arm_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Usb;
  d.vendor_id = 0x1209;
  d.product_id = 0xB15D;
  d.serial = std::move(serial);
  d.product = "bisturi sample arm";
  d.path = "virtual:sample-arm:" + d.serial;
  return d;
}

void put_int32(Bytes& p, std::size_t at, long value) {
  const auto u = static_cast<std::uint32_t>(static_cast<std::int32_t>(value));
  for (int i = 0; i < 4; ++i)
    p[at + i] = static_cast<std::uint8_t>((u >> (8 * i)) % 256u);
}

std::uint8_t parity(std::span<const std::uint8_t> p) {
  std::uint8_t x = 0;
  for (std::size_t i = 0; i < p.size(); ++i)
    x = static_cast<std::uint8_t>(x ^ p[i]);
  return x;
}

}  // namespace

SimulatedSampleArm::SimulatedSampleArm(DeviceScript script, std::string serial, double rate_hz)
    : SimulatedDevice(arm_descriptor(std::move(serial)),
                      Nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      script_(std::move(script)) {}

std::array<double, 3> SimulatedSampleArm::applied_force_N() const {
  std::lock_guard lock(mutex_);
  return force_N_;
}

std::uint64_t SimulatedSampleArm::rejected_packets() const {
  std::lock_guard lock(mutex_);
  return rejected_;
}

Bytes SimulatedSampleArm::input_report(Nanoseconds t) {
  Bytes p(24, 0);
  p[0] = 0x11;
  p[1] = sequence_++;
  p[2] = static_cast<std::uint8_t>(script_.buttons_at(t) & 7u);
  const Pose pose = script_.pose_at(t);
  put_int32(p, 4, std::lround(pose.position_m.x * 1e6));
  put_int32(p, 8, std::lround(pose.position_m.y * 1e6));
  put_int32(p, 12, std::lround(pose.position_m.z * 1e6));
  p[23] = parity(std::span<const std::uint8_t>(p).first(23));
  return p;
}

void SimulatedSampleArm::on_output(std::span<const std::uint8_t> p) {
  if (p.size() != 24 || p[0] != 0x12 || parity(p) != 0) {  // the XOR of all 24 bytes is zero
    ++rejected_;
    return;
  }
  std::array<double, 3> f{};
  for (std::size_t i = 0; i < 3; ++i) {
    const auto mN = static_cast<std::int16_t>(p[2 + 2 * i] + 256 * p[3 + 2 * i]);
    if (mN > 8000 || mN < -8000) {  // the firmware's own limit, per axis
      ++rejected_;
      return;
    }
    f[i] = mN / 1000.0;
  }
  force_N_ = f;
}

}  // namespace bisturi::devices
