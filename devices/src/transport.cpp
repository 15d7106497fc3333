#include "bisturi/devices/transport.h"

#include <cstdio>

namespace bisturi::devices {

const char* to_string(TransportKind kind) {
  switch (kind) {
    case TransportKind::Hid:
      return "hid";
    case TransportKind::Usb:
      return "usb";
    case TransportKind::Virtual:
      return "virtual";
  }
  return "unknown";
}

std::string describe(const DeviceDescriptor& device) {
  char ids[16];
  std::snprintf(ids, sizeof ids, "%04x:%04x", device.vendor_id, device.product_id);
  std::string out = device.product.empty() ? std::string("device") : device.product;
  out += " (";
  out += ids;
  if (!device.serial.empty()) out += ", serial " + device.serial;
  if (!device.path.empty()) out += ", path " + device.path;
  out += ")";
  return out;
}

ProtocolError::ProtocolError(const std::string& device, std::size_t offset,
                             const std::string& reason)
    : DeviceError(device + ": byte " + std::to_string(offset) + ": " + reason),
      device_(device),
      offset_(offset),
      reason_(reason) {}

Transport::~Transport() = default;

bool Transport::write_preempting(std::span<const std::uint8_t>) noexcept {
  return false;
}

bool Transport::read_into(Bytes& report, std::chrono::microseconds timeout) {
  std::optional<Bytes> r = read(timeout);
  if (!r) return false;
  report = std::move(*r);
  return true;
}
DeviceSource::~DeviceSource() = default;

}  // namespace bisturi::devices
