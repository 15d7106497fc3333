// The real transports: HID devices through hidapi (hidraw backend, non-blocking reads) and
// vendor-specific USB devices through libusb's asynchronous interrupt transfers (usb_async.h), so
// a zero-timeout read never waits. Enumeration is polled (DeviceManager) for hot-plug.
// These machines have no USB: the tests drive the drivers through virtual transports and the
// asynchronous USB logic through an in-process bus (docs/devices/usb-transport.md).
#pragma once

#include <cstdint>
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

// One alternate setting of a USB interface as its configuration descriptor gives it (what
// choose_usb_endpoints reads; libusb-free so that it can be tested without a device).
struct UsbAltSetting {
  int interface_number = 0;
  std::uint8_t interface_class = 0;  // 0xff: vendor-specific
  struct Endpoint {
    std::uint8_t address = 0;     // bit 7 set: IN
    std::uint8_t attributes = 0;  // bits 0-1: transfer type (3: interrupt)
    std::uint16_t max_packet_size = 64;
  };
  std::vector<Endpoint> endpoints;
};

struct UsbEndpoints {
  int interface = -1;  // -1: none fits
  std::uint8_t in = 0, out = 0;
  std::uint16_t in_size = 64;
};

// The interface a driver talks to among a device's alternate settings: the one `declared` names
// (its number, with interrupt IN and OUT endpoints at the declared addresses where given), or the
// first vendor-specific one with an interrupt IN and an interrupt OUT endpoint.
UsbEndpoints choose_usb_endpoints(const std::vector<UsbAltSetting>& settings,
                                  const UsbInterface& declared = {});

// libusb. Lists devices whose vendor/product id is in `wanted` (all devices with a
// vendor-specific interface when empty) and opens the interface `interface` chooses
// (choose_usb_endpoints), as an AsyncUsbTransport with a libusb context of its own.
class UsbSource final : public DeviceSource {
 public:
  explicit UsbSource(std::vector<UsbId> wanted = {}, UsbInterface interface = {});
  ~UsbSource() override;
  std::vector<DeviceDescriptor> enumerate() override;
  std::unique_ptr<Transport> open(const DeviceDescriptor& device) override;

 private:
  struct Context;
  std::vector<UsbId> wanted_;
  UsbInterface interface_;
  std::unique_ptr<Context> context_;
};

// The USB ids the registry's drivers claim (for UsbSource).
std::vector<UsbId> usb_ids(const Registry& registry);

}  // namespace bisturi::devices
