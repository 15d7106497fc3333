// The vendor arm's twin. It encodes and checks its packets with code of its own, written from
// docs/devices/vendor-haptic-protocol.md (constants, byte packing, a table-driven CRC), not with
// the driver's: a mistake in the driver's encoder cannot hide behind the same mistake here.
#include <algorithm>
#include <array>
#include <cmath>

#include "bisturi/devices/simulated.h"

namespace bisturi::devices {

namespace {

// The protocol as the document gives it.
namespace wire {
constexpr std::uint16_t kVendorId = 0x1209;
constexpr std::uint16_t kProductId = 0xB157;
constexpr std::size_t kPacketSize = 32;
constexpr std::uint8_t kVersion = 1;
constexpr std::uint8_t kState = 0x01, kInfo = 0x02, kForce = 0x10, kGetInfo = 0x11;
constexpr std::uint8_t kForcesActive = 0x01, kDeviceWatchdog = 0x02;

// CRC-16/CCITT-FALSE by a 256-entry table (the driver computes it bit by bit).
constexpr std::array<std::uint16_t, 256> crc_table() {
  std::array<std::uint16_t, 256> table{};
  for (unsigned i = 0; i < 256; ++i) {
    unsigned v = i << 8;
    for (int k = 0; k < 8; ++k)
      v = (v & 0x8000u) ? ((v << 1) ^ 0x1021u) : (v << 1);
    table[i] = static_cast<std::uint16_t>(v & 0xFFFFu);
  }
  return table;
}
constexpr auto kCrcTable = crc_table();

std::uint16_t crc(const std::uint8_t* bytes, std::size_t n) {
  unsigned value = 0xFFFFu;
  for (std::size_t i = 0; i < n; ++i)
    value = ((value << 8) ^ kCrcTable[((value >> 8) ^ bytes[i]) & 0xFFu]) & 0xFFFFu;
  return static_cast<std::uint16_t>(value);
}

using Packet = std::array<std::uint8_t, kPacketSize>;

void put16(Packet& p, std::size_t at, std::int64_t value) {
  const auto u = static_cast<std::uint16_t>(value & 0xFFFF);
  p[at] = static_cast<std::uint8_t>(u & 0xFFu);
  p[at + 1] = static_cast<std::uint8_t>(u >> 8);
}
void put32(Packet& p, std::size_t at, std::int64_t value) {
  const auto u = static_cast<std::uint32_t>(value & 0xFFFFFFFF);
  for (std::size_t i = 0; i < 4; ++i)
    p[at + i] = static_cast<std::uint8_t>((u >> (8 * i)) & 0xFFu);
}
std::int16_t get16(std::span<const std::uint8_t> p, std::size_t at) {
  return static_cast<std::int16_t>(static_cast<std::uint16_t>(p[at] | (p[at + 1] << 8)));
}

// Bytes 30-31: the CRC of bytes 0-29, low byte first.
Bytes sealed(Packet p) {
  const std::uint16_t c = crc(p.data(), 30);
  p[30] = static_cast<std::uint8_t>(c & 0xFFu);
  p[31] = static_cast<std::uint8_t>(c >> 8);
  return Bytes(p.begin(), p.end());
}
bool intact(std::span<const std::uint8_t> p) {
  return p.size() == kPacketSize &&
         crc(p.data(), 30) == static_cast<std::uint16_t>(p[30] | (p[31] << 8));
}
}  // namespace wire

constexpr Nanoseconds kDeviceWatchdog = std::chrono::milliseconds(100);

DeviceDescriptor arm_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Usb;
  d.vendor_id = wire::kVendorId;
  d.product_id = wire::kProductId;
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
  wire::Packet p{};
  p[0] = wire::kState;
  p[1] = sequence_++;
  wire::put16(p, 2, static_cast<std::int64_t>(script_.buttons_at(t) & 0xFFFF));
  const Pose pose = script_.pose_at(t);
  const double xyz[3] = {pose.position_m.x, pose.position_m.y, pose.position_m.z};
  for (std::size_t i = 0; i < 3; ++i)  // micrometres
    wire::put32(p, 4 + 4 * i, std::llround(std::clamp(xyz[i] * 1e6, -2e9, 2e9)));
  const double q[4] = {pose.orientation.w, pose.orientation.x, pose.orientation.y,
                       pose.orientation.z};
  for (std::size_t i = 0; i < 4; ++i)  // 1.0 = 16384
    wire::put16(p, 16 + 2 * i, std::llround(std::clamp(q[i], -1.0, 1.0) * 16384));
  const bool active = force_N_.x != 0 || force_N_.y != 0 || force_N_.z != 0;
  p[24] = static_cast<std::uint8_t>((active ? wire::kForcesActive : 0) |
                                    (watchdog_tripped_ ? wire::kDeviceWatchdog : 0));
  return wire::sealed(p);
}

void SimulatedArm::on_output(std::span<const std::uint8_t> p) {
  if (!wire::intact(p)) {
    ++bad_packets_;
    return;
  }
  if (p[0] == wire::kGetInfo) {
    wire::Packet info{};
    info[0] = wire::kInfo;
    info[1] = wire::kVersion;
    wire::put16(info, 2, std::llround(max_force_N_ * 100));  // centinewtons
    wire::put16(info, 4, std::llround(max_rate_));           // N/s
    info[6] = 2;                                             // buttons
    wire::put16(info, 7, std::llround(kMaxStiffness_N_per_m));
    for (std::size_t i = 0; i < 3; ++i) {  // millimetres, device frame
      wire::put16(info, 9 + 2 * i, std::llround(kWorkspaceMin_m[i] * 1000));
      wire::put16(info, 15 + 2 * i, std::llround(kWorkspaceMax_m[i] * 1000));
    }
    const Bytes answer = wire::sealed(info);
    send_locked(answer);
  } else if (p[0] == wire::kForce) {
    double f[3];
    for (std::size_t i = 0; i < 3; ++i)
      f[i] = wire::get16(p, 2 + 2 * i) / 1000.0;  // millinewtons
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
