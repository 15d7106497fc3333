// The real transports: HID devices through hidapi (hidraw backend, non-blocking reads) and
// vendor-specific USB devices through libusb's asynchronous interrupt transfers (usb_async.h), so
// a zero-timeout read never waits. Enumeration is polled (DeviceManager) for hot-plug.
// These machines have no USB: the tests drive the drivers through virtual transports and the
// asynchronous USB logic through an in-process bus (docs/devices/usb-transport.md).
#pragma once

#include <memory>
#include <vector>

#include "bisturi/devices/registry.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

// hidapi. enumerate() fills the report descriptor from sysfs (hidraw), so the registry can pick
// the generic drivers from it. vendor_id/product_id 0 list every HID device.
class HidSource final : public DeviceSource {
 public:
  explicit HidSource(std::uint16_t vendor_id = 0, std::uint16_t product_id = 0);
  ~HidSource() override;
  std::vector<DeviceDescriptor> enumerate() override;
  std::unique_ptr<Transport> open(const DeviceDescriptor& device) override;

 private:
  std::uint16_t vendor_id_, product_id_;
};

// libusb. Lists devices whose vendor/product id is in `wanted` (all devices with a
// vendor-specific interface when empty) and opens the first vendor-specific interface with an
// interrupt IN and an interrupt OUT endpoint, as an AsyncUsbTransport with a libusb context of
// its own.
class UsbSource final : public DeviceSource {
 public:
  explicit UsbSource(std::vector<UsbId> wanted = {});
  ~UsbSource() override;
  std::vector<DeviceDescriptor> enumerate() override;
  std::unique_ptr<Transport> open(const DeviceDescriptor& device) override;

 private:
  struct Context;
  std::vector<UsbId> wanted_;
  std::unique_ptr<Context> context_;
};

// The USB ids the registry's drivers claim (for UsbSource).
std::vector<UsbId> usb_ids(const Registry& registry);

}  // namespace bisturi::devices
