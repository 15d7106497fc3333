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

class SimulatedDevice;
struct DeviceScript;

// Makes the driver's simulated twin (simulated.h), which speaks the hardware's bytes through a
// virtual transport: what a scene's `simulated = true` device opens. `serial`: the scene's serial,
// "" for the twin's own; `haptic_hz`: the session's haptic rate (a twin that reports at a rate of
// its own, like a head tracker, may ignore it).
using TwinFactory = std::function<std::unique_ptr<SimulatedDevice>(
    const DeviceScript& script, const std::string& serial, double haptic_hz)>;

// What the session sends on a force channel.
enum class ChannelUse : std::uint8_t {
  Vector,  // 3 components: the contact force vector in the device's frame (the session maps it
           // through the scene's device-to-scene transform)
  Finger,  // 1 component: the force of one finger's own contact, a scalar along the actuator
  Unused,  // left at zero (a vibration motor no contact drives)
};
const char* to_string(ChannelUse use);

// What pressing a button does to the session's instrument.
enum class ButtonUse : std::uint8_t {
  None,
  Cut,     // held: the scalpel's blade sweeps; released: the incision is made
  Grasp,   // held: the grasper's jaws close on the tissue (a glove closes them with its fingers)
  Clutch,  // held: the instrument stays while the handle moves (re-centring a grounded arm)
};
const char* to_string(ButtonUse use);
// The bits of the buttons (by index in `uses`, up to 64) that have `use`.
std::uint64_t buttons_with(const std::vector<ButtonUse>& uses, ButtonUse use);

struct ChannelRole {
  ChannelUse use = ChannelUse::Unused;
  std::uint8_t finger = 0;  // Finger: 0 thumb, 1 index, 2 middle, 3 ring, 4 little
  bool operator==(const ChannelRole&) const = default;
};

// A driver's channel layout: the roles of its force channels, in Capabilities::force_channels
// order. Channels past the list (a HID glove's come from its descriptor) get a role from their
// shape: 3 components -> Vector; 1 component with a force unit -> Finger, the next finger in
// order; anything else (unitless, a sixth finger) -> Unused.
struct ChannelLayout {
  std::vector<ChannelRole> channels;
  // One role per channel of an opened device. A listed role that does not fit the channel (a
  // Vector on a 1-component channel) becomes Unused: the session sends that channel zero.
  std::vector<ChannelRole> roles(const Capabilities& capabilities) const;
  // By button bit, what the button does (ButtonUse). Empty: button 0 cuts (a glove's or a
  // controller's trigger) and a grasp comes from the fingers closing.
  std::vector<ButtonUse> buttons;
  // One use per button of an opened device (the defaults above, None past the list).
  std::vector<ButtonUse> button_uses(const Capabilities& capabilities) const;
};

// Which interface and endpoints of a raw USB device a driver talks to (libusb, UsbSource). The
// defaults pick the first vendor-specific interface with an interrupt IN and an interrupt OUT
// endpoint; a driver whose device has several, or other classes first, names its own.
struct UsbInterface {
  int number = -1;                // bInterfaceNumber; -1: the first vendor-specific one that fits
  std::uint8_t in_endpoint = 0;   // bEndpointAddress of the interrupt IN endpoint (0x81); 0: any
  std::uint8_t out_endpoint = 0;  // and of the interrupt OUT endpoint (0x01); 0: any
  bool operator==(const UsbInterface&) const = default;
};

struct DriverInfo {
  std::string name;            // unique: "hid-glove", "vendor-arm", ...
  std::string summary;         // one line for listings
  std::vector<UsbId> usb_ids;  // exact matches, tried first
  // Optional: claims devices it recognises otherwise (a HID descriptor describing a glove).
  std::function<bool(const DeviceDescriptor&)> matches;
  DriverFactory create;
  // Where its hardware is found: Hid -> hidapi (HidSource), Usb -> libusb (UsbSource), Virtual ->
  // nowhere (a driver for twins or traces only).
  TransportKind bus = TransportKind::Virtual;
  UsbInterface usb_interface;  // bus Usb: the interface and endpoints it talks to
  DeviceClass device_class = DeviceClass::HapticGlove;  // what it opens
  TwinFactory make_twin;                                // empty: no twin
  ChannelLayout layout;
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

// Adds the drivers built into this library (`bisturi device list` lists them, with their ids,
// twins, channels and buttons). The template in devices/sample/ is not among them.
void register_builtin_drivers(Registry& registry);

// A registry holding the built-in drivers.
Registry builtin_registry();

}  // namespace bisturi::devices
