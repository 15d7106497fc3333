// Drivers register by name and by USB vendor/product id; open() picks one for a transport. Replay
// rebuilds the recorded drivers from the descriptors in a trace (descriptor.driver names one).
#pragma once

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

struct UsbId {
  std::uint16_t vendor_id = 0;
  std::uint16_t product_id = 0;
  bool operator==(const UsbId&) const = default;
};

using DriverFactory =
    std::function<std::unique_ptr<Device>(std::unique_ptr<Transport>, Clock& clock)>;

struct DriverInfo {
  std::string name;            // unique: "hid-glove", "vendor-arm", ...
  std::string summary;         // one line for listings
  std::vector<UsbId> usb_ids;  // exact matches, tried first
  // Optional: claims devices it recognises otherwise (a HID descriptor describing a glove).
  std::function<bool(const DeviceDescriptor&)> matches;
  DriverFactory create;
};

class Registry {
 public:
  // Throws std::invalid_argument on an empty or duplicate name or a missing factory.
  void add(DriverInfo driver);

  const DriverInfo* find_by_name(std::string_view name) const;
  const DriverInfo* find_by_usb_id(UsbId id) const;
  // descriptor.driver by name when set, then the USB id, then each driver's matches() in
  // registration order. nullptr when none fits.
  const DriverInfo* find(const DeviceDescriptor& device) const;

  // Opens the driver that find() picks on the transport; the device's descriptor().driver is then
  // that driver's name. Throws DeviceError when no driver fits (naming the device), or what the
  // driver throws (ProtocolError on a malformed descriptor).
  std::unique_ptr<Device> open(std::unique_ptr<Transport> transport,
                               Clock& clock = steady_clock()) const;

  const std::vector<DriverInfo>& drivers() const { return drivers_; }

 private:
  std::vector<DriverInfo> drivers_;
};

// Adds the drivers built into this library: "hid-glove" (generic HID glove), "hid-tracker"
// (generic HID head tracker) and "vendor-arm" (the libusb haptic arm).
void register_builtin_drivers(Registry& registry);

// A registry holding the built-in drivers.
Registry builtin_registry();

}  // namespace bisturi::devices
