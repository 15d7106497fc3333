// The session's devices, simulated or real (see session_devices.h).

#include "bisturi/runtime/session/session_devices.h"

#include <algorithm>
#include <cstdio>
#include <utility>

#include "bisturi/devices/host_transports.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/virtual_transport.h"

namespace bisturi::runtime {

namespace {

std::string hex4(std::uint16_t v) {
  char text[8];
  std::snprintf(text, sizeof text, "%04x", v);
  return text;
}

/// "device 'glove' (driver hid-glove, 1234:5678, serial S)": how errors name a scene device.
std::string describe(const DeviceDescription& d) {
  std::string s = "device '" + d.name + "' (";
  s += d.driver.empty() ? std::string("any driver") : "driver " + d.driver;
  if (d.vendor_id != 0 || d.product_id != 0)
    s += ", " + hex4(d.vendor_id) + ":" + hex4(d.product_id);
  if (!d.serial.empty()) s += ", serial " + d.serial;
  return s + ")";
}

const devices::DriverInfo* driver_for(const DeviceDescription& d,
                                      const devices::Registry& registry) {
  const devices::DriverInfo* driver = d.driver.empty()
                                          ? registry.find_by_usb_id({d.vendor_id, d.product_id})
                                          : registry.find_by_name(d.driver);
  if (driver == nullptr) {
    std::string known;
    for (const devices::DriverInfo& i : registry.drivers())
      known += (known.empty() ? "" : ", ") + i.name;
    throw SceneFileError(
        describe(d) + ": no registered driver " +
        (d.driver.empty() ? "claims that vendor/product id" : "is named '" + d.driver + "'") +
        " (drivers: " + known + ")");
  }
  return driver;
}

/// Where the driver's hardware is listed: the bus it registered, never its name.
std::unique_ptr<devices::DeviceSource> source_for(const devices::DriverInfo& driver,
                                                  const DeviceDescription& d,
                                                  const devices::Registry& registry) {
  switch (driver.bus) {
    case devices::TransportKind::Hid:
      return std::make_unique<devices::HidSource>(d.vendor_id, d.product_id);
    case devices::TransportKind::Usb: {
      std::vector<devices::UsbId> wanted = devices::usb_ids(registry);
      if (d.vendor_id != 0 && d.product_id != 0) wanted.push_back({d.vendor_id, d.product_id});
      return std::make_unique<devices::UsbSource>(std::move(wanted), driver.usb_interface);
    }
    case devices::TransportKind::Virtual:
      break;
  }
  throw SceneFileError(describe(d) + ": driver '" + driver.name +
                       "' has no hardware bus (it runs on twins and traces only): set "
                       "simulated = true");
}

}  // namespace

DeviceChoice choose_session_devices(const SceneDescription& scene) {
  DeviceChoice c;
  const auto by_name = [&](const std::string& name) -> const DeviceDescription* {
    for (const DeviceDescription& d : scene.devices)
      if (d.name == name) return &d;
    return nullptr;
  };
  std::vector<const DeviceDescription*> named;
  for (const InstrumentDescription& in : scene.instruments) {
    if (in.device.empty()) continue;
    const DeviceDescription* d = by_name(in.device);
    if (d == nullptr || d->role != DeviceDescription::Role::Haptic)
      throw SceneFileError(scene.name + ": instrument '" + in.name + "' names device '" +
                           in.device + "', which is not a haptic device of the scene");
    named.push_back(d);
  }
  for (const DeviceDescription& d : scene.devices) {
    const bool hand = d.role == DeviceDescription::Role::Haptic &&
                      (named.empty() || std::find(named.begin(), named.end(), &d) != named.end());
    if (hand) c.hands.push_back(&d);
    if (d.role == DeviceDescription::Role::HeadTracker && c.head == nullptr) c.head = &d;
  }
  if (c.hands.empty())
    throw SceneFileError(scene.name + ": the session needs a device with role = \"haptic\"");
  c.haptic = c.hands.front();
  if (c.head == nullptr)
    throw SceneFileError(scene.name + ": the session needs a device with role = \"head-tracker\"");
  return c;
}

devices::DeviceDescriptor find_real_device(const DeviceDescription& d,
                                           const devices::Registry& registry,
                                           const std::vector<devices::DeviceDescriptor>& listed) {
  const devices::DriverInfo* driver = driver_for(d, registry);
  for (const devices::DeviceDescriptor& candidate : listed) {
    if (d.vendor_id != 0 && candidate.vendor_id != d.vendor_id) continue;
    if (d.product_id != 0 && candidate.product_id != d.product_id) continue;
    if (!d.serial.empty() && candidate.serial != d.serial) continue;
    // The driver must recognise the device (its USB id, or its HID descriptor), unless the scene
    // names the device by id too: then the named driver is used as asked.
    const bool named_by_id = d.vendor_id != 0 && d.product_id != 0;
    bool claimed = named_by_id;
    for (const devices::UsbId& id : driver->usb_ids)
      claimed = claimed || (id == devices::UsbId{candidate.vendor_id, candidate.product_id});
    claimed = claimed || (driver->matches && driver->matches(candidate));
    if (!claimed) continue;
    devices::DeviceDescriptor chosen = candidate;
    chosen.driver = driver->name;
    return chosen;
  }
  std::string seen;
  for (const devices::DeviceDescriptor& candidate : listed)
    seen += (seen.empty() ? "" : "; ") + devices::describe(candidate);
  throw devices::DeviceError(
      describe(d) + ": not connected (" +
      (listed.empty() ? std::string("no device of that kind is connected") : "connected: " + seen) +
      "); set simulated = true to use its simulated twin");
}

SessionDevices::SessionDevices(const SceneDescription& scene, const Procedure& procedure,
                               const devices::Registry& registry, devices::Clock& clock,
                               devices::TraceWriter* writer, InProcessTransports in_process)
    : choice_(choose_session_devices(scene)),
      haptic_hz_(scene.rates.haptic_hz),
      in_process_(std::move(in_process)) {
  const std::string where = scene.file.empty() ? scene.name + " scene" : scene.file.string();
  hands_.resize(choice_.hands.size());
  try {
    for (std::size_t i = 0; i < hands_.size(); ++i) {
      Hand& hand = hands_[i];
      const std::size_t twins_before = twins_.size();
      const devices::DeviceScript& script =
          i == 0 ? procedure.first_hand
                 : (i - 1 < procedure.other_hands.size() ? procedure.other_hands[i - 1]
                                                         : procedure.first_hand);
      hand.device = open_one(*choice_.hands[i], script, registry, clock, writer, &hand.trace_index,
                             &hand.write_bounded);
      if (twins_.size() > twins_before) hand.twin = twins_.back().get();
    }
    head_device_ =
        open_one(*choice_.head, procedure.head, registry, clock, writer, nullptr, nullptr);
  } catch (const SceneFileError& e) {
    throw SceneFileError(where + ": " + e.what());
  } catch (const devices::DeviceError& e) {
    throw devices::DeviceError(where + ": " + e.what());
  }
  for (std::size_t i = 0; i < hands_.size(); ++i) {
    Hand& hand = hands_[i];
    hand.haptic = devices::as_haptic(hand.device.get());
    if (hand.haptic == nullptr)
      throw SceneFileError(describe(*choice_.hands[i]) + ": its driver '" +
                           hand.device->driver_name() + "' is not a haptic device");
    const devices::DriverInfo* driver = registry.find_by_name(hand.haptic->driver_name());
    const devices::ChannelLayout layout =
        driver != nullptr ? driver->layout : devices::ChannelLayout{};
    hand.roles = layout.roles(hand.haptic->capabilities());
    hand.buttons = layout.button_uses(hand.haptic->capabilities());
  }
  head_ = devices::as_tracker(head_device_.get());
  if (head_ == nullptr)
    throw SceneFileError(describe(*choice_.head) + ": its driver '" + head_device_->driver_name() +
                         "' is not a head tracker");
}

SessionDevices::~SessionDevices() = default;

std::unique_ptr<devices::Device> SessionDevices::open_one(
    const DeviceDescription& d, const devices::DeviceScript& script,
    const devices::Registry& registry, devices::Clock& clock, devices::TraceWriter* writer,
    std::uint16_t* trace_index, bool* write_bounded) {
  const devices::DriverInfo* driver = driver_for(d, registry);
  std::unique_ptr<devices::Transport> transport;
  if (d.simulated) {
    // The twin speaks the real device's bytes; the driver on the host side cannot tell.
    if (!driver->make_twin)
      throw SceneFileError(describe(d) + ": driver '" + driver->name +
                           "' registers no simulated twin (set simulated = false for hardware)");
    std::unique_ptr<devices::SimulatedDevice> twin =
        driver->make_twin(script, d.serial, haptic_hz_);
    devices::VirtualPair pair = devices::make_virtual_pair(twin->descriptor());
    twin->attach(std::move(pair.device));
    transport = std::move(pair.host);
    twins_.push_back(std::move(twin));
    summary_.push_back(d.name + ": " + driver->name + " (simulated)");
  } else if (driver->bus == devices::TransportKind::Virtual && in_process_ &&
             (transport = in_process_(*driver)) != nullptr) {
    // Fed from inside the process (the render thread's headset controller).
    summary_.push_back(d.name + ": " + driver->name + " (" +
                       devices::describe(transport->descriptor()) + ")");
  } else {
    std::unique_ptr<devices::DeviceSource> source = source_for(*driver, d, registry);
    const devices::DeviceDescriptor found = find_real_device(d, registry, source->enumerate());
    transport = source->open(found);
    summary_.push_back(d.name + ": " + driver->name + " (" + devices::describe(found) + ")");
  }
  if (write_bounded != nullptr) *write_bounded = transport->write_is_bounded();
  if (writer != nullptr) {
    devices::RecordedDevice r =
        devices::open_recorded(registry, std::move(transport), *writer, clock);
    if (trace_index != nullptr) *trace_index = r.index;
    return std::move(r.device);
  }
  return registry.open(std::move(transport), clock);
}

void SessionDevices::step_twins(devices::Nanoseconds t) {
  for (const auto& twin : twins_)
    twin->step(t);
}

std::vector<std::string> SessionDevices::summary() const {
  return summary_;
}

bool SessionDevices::unplug_haptic() {
  if (hands_.front().twin == nullptr) return false;
  hands_.front().twin->disconnect();
  return true;
}

bool SessionDevices::stall_haptic_io(devices::Nanoseconds duration) {
  if (hands_.front().twin == nullptr) return false;
  hands_.front().twin->stall_host_writes(duration);
  return true;
}

void SessionDevices::close() {
  for (Hand& hand : hands_) {
    if (hand.device) hand.device->close();
  }
  if (head_device_) head_device_->close();
}

}  // namespace bisturi::runtime
