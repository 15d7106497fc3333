#include <algorithm>
#include <cmath>

#include "bisturi/devices/hid_descriptor.h"
#include "bisturi/devices/simulated.h"
#include "descriptor_writer.h"

namespace bisturi::devices {

namespace {

// One input report, no report id (20 bytes): X Y Z int32 in 0.1 mm (unit cm, exponent -2),
// quaternion x y z w int16 (-1..1).
DeviceDescriptor tracker_descriptor(std::string serial) {
  DeviceDescriptor d;
  d.kind = TransportKind::Hid;
  d.vendor_id = 0x1209;
  d.product_id = 0xB151;
  d.serial = std::move(serial);
  d.product = "bisturi simulated head tracker";
  d.path = "virtual:head:" + d.serial;
  d.report_descriptor = SimulatedHeadTracker::report_descriptor();
  return d;
}

}  // namespace

Bytes SimulatedHeadTracker::report_descriptor() {
  detail::DescriptorWriter w;
  w.usage_page(hid::kPageVrControls).usage(0x05).collection(1);  // Head Tracker, application
  w.usage_page(hid::kPageGenericDesktop).usage(0x30).usage(0x31).usage(0x32);
  w.logical(-2147483647, 2147483647).unit(0x11, -2).size_count(32, 3).input(0x02);
  w.usage_page(hid::kPageSensors).usage(0x0483).logical(-16384, 16384).physical(-1, 1);
  w.unit(0, 0).size_count(16, 4).input(0x02);
  w.end_collection();
  return w.take();
}

SimulatedHeadTracker::SimulatedHeadTracker(DeviceScript script, std::string serial, double rate_hz)
    : SimulatedDevice(tracker_descriptor(std::move(serial)),
                      Nanoseconds(static_cast<std::int64_t>(1e9 / rate_hz))),
      script_(std::move(script)) {}

Bytes SimulatedHeadTracker::input_report(Nanoseconds t) {
  Bytes report(20, 0);
  const Pose pose = script_.pose_at(t);
  const double p[3] = {pose.position_m.x, pose.position_m.y, pose.position_m.z};
  for (std::size_t i = 0; i < 3; ++i) {
    const double tenth_mm = std::clamp(std::round(p[i] * 1e4), -2147483647.0, 2147483647.0);
    detail::put_le(report, 4 * i, static_cast<std::uint32_t>(static_cast<std::int32_t>(tenth_mm)),
                   4);
  }
  const double q[4] = {pose.orientation.x, pose.orientation.y, pose.orientation.z,
                       pose.orientation.w};
  for (std::size_t i = 0; i < 4; ++i) {
    const auto v = static_cast<std::int16_t>(std::lround(std::clamp(q[i], -1.0, 1.0) * 16384));
    detail::put_le(report, 12 + 2 * i, static_cast<std::uint16_t>(v), 2);
  }
  return report;
}

}  // namespace bisturi::devices
