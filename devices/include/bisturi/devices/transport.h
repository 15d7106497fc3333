// Transports: the byte pipes below every driver (hidapi, libusb, in-memory virtual). Drivers see
// only this interface, so tests and trace replay run the real driver code on bytes.
#pragma once

#include <chrono>
#include <cstdint>
#include <memory>
#include <optional>
#include <span>
#include <stdexcept>
#include <string>
#include <vector>

namespace bisturi::devices {

using Bytes = std::vector<std::uint8_t>;

enum class TransportKind : std::uint8_t { Hid, Usb, Virtual };

// "hid", "usb", "virtual".
const char* to_string(TransportKind kind);

// What a transport knows about the device at its other end. Recorded in trace headers, so replay
// can rebuild the same driver (Registry::open) from it.
struct DeviceDescriptor {
  TransportKind kind = TransportKind::Virtual;
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  std::string serial;
  std::string product;
  std::string path;         // OS path (hidraw node, "bus-port.port") or a virtual name
  Bytes report_descriptor;  // HID report descriptor; empty for raw USB
  std::string driver;       // driver name when known (set by the registry when opened)

  bool operator==(const DeviceDescriptor&) const = default;
};

// "product (vvvv:pppp, serial S, path P)": how errors name a device.
std::string describe(const DeviceDescriptor& device);

class DeviceError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

// The device went away (unplugged, transport closed). Its forces are stopped.
class DeviceDisconnected : public DeviceError {
 public:
  using DeviceError::DeviceError;
};

// A malformed report or descriptor. The message names the device, the byte offset and the reason.
class ProtocolError : public DeviceError {
 public:
  ProtocolError(const std::string& device, std::size_t offset, const std::string& reason);
  const std::string& device() const { return device_; }
  std::size_t offset() const { return offset_; }
  const std::string& reason() const { return reason_; }

 private:
  std::string device_;
  std::size_t offset_;
  std::string reason_;
};

class Transport {
 public:
  virtual ~Transport();
  virtual const DeviceDescriptor& descriptor() const = 0;
  // The next input report (for HID with its report id byte first when the device uses ids);
  // nullopt on timeout; throws DeviceDisconnected when the device is gone.
  virtual std::optional<Bytes> read(std::chrono::microseconds timeout) = 0;
  // read() into `report`, whose storage may be reused or swapped: true when a report came. The
  // default moves read()'s result in; a transport that can hand over a buffer without
  // allocating overrides it, so a driver's poll (Device::poll_transport) allocates nothing.
  virtual bool read_into(Bytes& report, std::chrono::microseconds timeout);
  // Sends one output report (HID: as the report descriptor lays it out, the id byte first only
  // when the descriptor uses report ids; raw USB: one interrupt packet). Throws
  // DeviceDisconnected when the device is gone.
  virtual void write(std::span<const std::uint8_t> report) = 0;
  // Sends one report from any thread while another may be inside write(), without waiting for
  // it: no lock, no allocation, bounded. The force path's emergency zero goes this way when the
  // haptic tick is stuck in the device's I/O. False where the transport cannot (the default).
  virtual bool write_preempting(std::span<const std::uint8_t> report) noexcept;
  // Whether write() returns within a bound the transport sets (a timeout), whatever the device
  // does. False where a stalled device can hold it indefinitely (hidapi's hid_write).
  virtual bool write_is_bounded() const { return true; }
};

// Something that lists devices and opens transports to them: hidapi, libusb, a virtual bus, a
// trace. Hot-plug is found by polling enumerate() (see hotplug.h).
class DeviceSource {
 public:
  virtual ~DeviceSource();
  virtual std::vector<DeviceDescriptor> enumerate() = 0;
  // Throws DeviceError when it cannot be opened (gone, permissions).
  virtual std::unique_ptr<Transport> open(const DeviceDescriptor& device) = 0;
};

}  // namespace bisturi::devices
