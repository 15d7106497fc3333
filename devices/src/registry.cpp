#include "bisturi/devices/registry.h"

#include <stdexcept>

#include "bisturi/devices/controller/openxr_controller.h"
#include "bisturi/devices/hid_drivers.h"
#include "bisturi/devices/vendor_arm.h"

namespace bisturi::devices {

const char* to_string(ChannelUse use) {
  switch (use) {
    case ChannelUse::Vector:
      return "vector";
    case ChannelUse::Finger:
      return "finger";
    case ChannelUse::Unused:
      return "unused";
  }
  return "unknown";
}

const char* to_string(ButtonUse use) {
  switch (use) {
    case ButtonUse::None:
      return "none";
    case ButtonUse::Cut:
      return "cut";
    case ButtonUse::Grasp:
      return "grasp";
    case ButtonUse::Clutch:
      return "clutch";
  }
  return "unknown";
}

std::uint64_t buttons_with(const std::vector<ButtonUse>& uses, ButtonUse use) {
  std::uint64_t bits = 0;
  for (std::size_t i = 0; i < uses.size() && i < 64; ++i)
    if (uses[i] == use) bits |= std::uint64_t{1} << i;
  return bits;
}

std::vector<ButtonUse> ChannelLayout::button_uses(const Capabilities& capabilities) const {
  std::vector<ButtonUse> out(capabilities.buttons, ButtonUse::None);
  if (buttons.empty()) {
    if (!out.empty()) out[0] = ButtonUse::Cut;
    return out;
  }
  for (std::size_t i = 0; i < out.size() && i < buttons.size(); ++i)
    out[i] = buttons[i];
  return out;
}

std::vector<ChannelRole> ChannelLayout::roles(const Capabilities& capabilities) const {
  std::vector<ChannelRole> out;
  std::uint8_t next_finger = 0;
  for (std::size_t i = 0; i < capabilities.force_channels.size(); ++i) {
    const ForceChannel& channel = capabilities.force_channels[i];
    ChannelRole role;
    if (i < channels.size()) {
      role = channels[i];
      const bool fits =
          role.use == ChannelUse::Unused ||
          (role.use == ChannelUse::Vector && channel.components == 3) ||
          (role.use == ChannelUse::Finger && channel.components == 1 && role.finger < 5);
      if (!fits) role = ChannelRole{};
    } else if (channel.components == 3) {
      role.use = ChannelUse::Vector;
    } else if (channel.components == 1 && !channel.unitless && next_finger < 5) {
      role = ChannelRole{ChannelUse::Finger, next_finger};
    }
    if (role.use == ChannelUse::Finger) next_finger = static_cast<std::uint8_t>(role.finger + 1);
    out.push_back(role);
  }
  return out;
}

void Registry::add(DriverInfo driver) {
  if (driver.name.empty()) throw std::invalid_argument("registry: a driver needs a name");
  if (!driver.create)
    throw std::invalid_argument("registry: driver " + driver.name + " has no factory");
  if (find_by_name(driver.name)) {
    throw std::invalid_argument("registry: driver " + driver.name + " is registered already");
  }
  drivers_.push_back(std::move(driver));
}

const DriverInfo* Registry::find_by_name(std::string_view name) const {
  for (const auto& driver : drivers_) {
    if (driver.name == name) return &driver;
  }
  return nullptr;
}

const DriverInfo* Registry::find_by_usb_id(UsbId id) const {
  for (const auto& driver : drivers_) {
    for (const auto& known : driver.usb_ids) {
      if (known == id) return &driver;
    }
  }
  return nullptr;
}

const DriverInfo* Registry::find(const DeviceDescriptor& device) const {
  if (!device.driver.empty()) return find_by_name(device.driver);
  if (const auto* driver = find_by_usb_id({device.vendor_id, device.product_id})) return driver;
  for (const auto& driver : drivers_) {
    if (driver.matches && driver.matches(device)) return &driver;
  }
  return nullptr;
}

std::unique_ptr<Device> Registry::open(std::unique_ptr<Transport> transport, Clock& clock) const {
  if (!transport) throw std::invalid_argument("registry: open needs a transport");
  const DeviceDescriptor& device = transport->descriptor();
  const DriverInfo* driver = find(device);
  if (!driver) {
    if (!device.driver.empty()) {
      throw DeviceError(describe(device) + ": driver '" + device.driver + "' is not registered");
    }
    throw DeviceError(describe(device) + ": no driver for this device");
  }
  return driver->create(std::move(transport), clock);
}

void register_builtin_drivers(Registry& registry) {
  registry.add(vendor_arm_driver_info());
  registry.add(hid_glove_driver_info());
  registry.add(hid_tracker_driver_info());
  registry.add(openxr_controller_driver_info());
}

Registry builtin_registry() {
  Registry registry;
  register_builtin_drivers(registry);
  return registry;
}

}  // namespace bisturi::devices
