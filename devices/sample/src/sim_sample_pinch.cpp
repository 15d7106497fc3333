// The sample pinch grip's twin. It writes and checks its bytes with code of its own, from the
// protocol in sample_pinch.h, never with the driver's: a mistake on one side cannot hide behind
// the same mistake on the other.
#include <cmath>

#include "bisturi/devices/sample/sample_pinch.h"

namespace bisturi::devices {

namespace {

DeviceDescriptor pinch_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Usb;
  d.vendor_id = 0x1209;
  d.product_id = 0xB15C;
  d.serial = std::move(serial);
  d.product = "bisturi sample pinch grip";
  d.path = "virtual:pinch:" + d.serial;
  return d;
}

// Byte 15 is minus the sum of bytes 0-14.
void close_sum(Bytes& p) {
  std::uint8_t sum = 0;
  for (std::size_t i = 0; i < 15; ++i)
    sum = static_cast<std::uint8_t>(sum + p[i]);
  p[15] = static_cast<std::uint8_t>(0x100 - sum);
}

bool sums_to_zero(std::span<const std::uint8_t> p) {
  std::uint8_t sum = 0;
  for (std::uint8_t b : p)
    sum = static_cast<std::uint8_t>(sum + b);
  return sum == 0;
}

}  // namespace

SimulatedPinch::SimulatedPinch(DeviceScript script, std::string serial, double rate_hz)
    : SimulatedDevice(pinch_descriptor(std::move(serial)),
                      Nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      script_(std::move(script)) {}

std::array<double, 2> SimulatedPinch::applied_forces_N() const {
  std::lock_guard lock(mutex_);
  return forces_N_;
}

std::uint64_t SimulatedPinch::rejected_packets() const {
  std::lock_guard lock(mutex_);
  return rejected_;
}

Bytes SimulatedPinch::input_report(Nanoseconds t) {
  Bytes p(16, 0);
  p[0] = 0x01;
  p[1] = sequence_++;
  p[2] = static_cast<std::uint8_t>(script_.buttons_at(t) & 1u);
  const std::vector<double> joints = script_.joints_at(t, 2);
  for (std::size_t j = 0; j < 2; ++j) {
    const long tenths_of_mrad = std::lround(std::fmax(-3.2767, std::fmin(3.2767, joints[j])) * 1e4);
    const auto word = static_cast<std::uint16_t>(static_cast<std::int16_t>(tenths_of_mrad));
    p[4 + 2 * j] = static_cast<std::uint8_t>(word % 256);
    p[5 + 2 * j] = static_cast<std::uint8_t>(word / 256);
  }
  close_sum(p);
  return p;
}

void SimulatedPinch::on_output(std::span<const std::uint8_t> p) {
  if (p.size() != 16 || !sums_to_zero(p) || p[0] != 0x02) {
    ++rejected_;
    return;
  }
  const unsigned thumb_mN = p[2] + 256u * p[3];
  const unsigned index_mN = p[4] + 256u * p[5];
  if (thumb_mN > 4000 || index_mN > 4000) {  // the firmware's own limit
    ++rejected_;
    return;
  }
  forces_N_ = {thumb_mN / 1000.0, index_mN / 1000.0};
}

}  // namespace bisturi::devices
