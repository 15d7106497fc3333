// libFuzzer: input reports through the generic HID drivers (report parser + usage mapping).
// Byte 0 picks the descriptor: even = the simulated glove's, odd = the head tracker's, and with
// bit 1 set the next two bytes give the length of a fuzzed descriptor that follows. The rest is
// one input report.
#include <cstdint>
#include <span>

#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/virtual_transport.h"

namespace {
const bisturi::devices::Bytes& glove() {
  static const auto bytes = bisturi::devices::SimulatedGlove::report_descriptor();
  return bytes;
}
const bisturi::devices::Bytes& tracker() {
  static const auto bytes = bisturi::devices::SimulatedHeadTracker::report_descriptor();
  return bytes;
}
}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  namespace bd = bisturi::devices;
  if (size < 1) return 0;
  const std::uint8_t mode = data[0];
  std::span<const std::uint8_t> rest(data + 1, size - 1);
  bd::DeviceDescriptor device;
  device.kind = bd::TransportKind::Hid;
  device.report_descriptor = (mode & 1) ? tracker() : glove();
  if (mode & 2) {
    if (rest.size() < 2) return 0;
    const std::size_t n = std::min<std::size_t>(rest[0] | rest[1] << 8, rest.size() - 2);
    device.report_descriptor.assign(rest.begin() + 2, rest.begin() + 2 + static_cast<long>(n));
    rest = rest.subspan(2 + n);
  }
  bd::VirtualClock clock;
  try {
    auto pair = bd::make_virtual_pair(device);
    std::unique_ptr<bd::Device> driver;
    if (mode & 1) {
      driver = bd::open_hid_tracker(std::move(pair.host), clock);
    } else {
      driver = bd::open_hid_glove(std::move(pair.host), clock);
    }
    driver->handle_report(rest);
    if (auto* haptic = bd::as_haptic(driver.get())) {
      std::vector<double> forces(haptic->capabilities().force_components(), 1e9);
      haptic->send_forces(forces);
    }
  } catch (const bd::ProtocolError&) {
  }
  return 0;
}
