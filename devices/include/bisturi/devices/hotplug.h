// Hot-plug by polling: a DeviceManager lists its sources (hidapi, libusb, virtual buses), opens a
// driver on each new device through the registry, notices devices that went away, and picks them
// up again when they come back. The session goes on through all of it.
#pragma once

#include <map>
#include <memory>
#include <set>
#include <string>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"

namespace bisturi::devices {

class DeviceManager {
 public:
  // registry, clock and the sources must outlive the manager.
  DeviceManager(const Registry& registry, Clock& clock);
  ~DeviceManager();

  void add_source(DeviceSource& source);
  // Lists every source and returns what changed, in order: Disconnected (an open device whose
  // transport failed, or that is no longer listed), Removed, Arrived, Opened / Reconnected (a
  // device seen before, keyed by its path), OpenFailed (not retried until it leaves and returns).
  std::vector<DeviceEvent> scan();
  // The open devices, in the order they were opened.
  std::vector<Device*> devices() const;
  // The open device at this path, or nullptr.
  Device* find(const std::string& path) const;

 private:
  struct Entry {
    DeviceDescriptor device;
    DeviceSource* source = nullptr;
    std::unique_ptr<Device> driver;
    bool failed = false;
    std::uint64_t order = 0;
  };
  const Registry& registry_;
  Clock& clock_;
  std::vector<DeviceSource*> sources_;
  std::map<std::string, Entry> entries_;
  std::set<std::string> opened_before_;
  std::uint64_t next_order_ = 0;
};

}  // namespace bisturi::devices
