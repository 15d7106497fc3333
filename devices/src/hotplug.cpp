#include "bisturi/devices/hotplug.h"

#include <algorithm>

namespace bisturi::devices {

DeviceManager::DeviceManager(const Registry& registry, Clock& clock)
    : registry_(registry), clock_(clock) {}

DeviceManager::~DeviceManager() = default;

void DeviceManager::add_source(DeviceSource& source) {
  sources_.push_back(&source);
}

std::vector<DeviceEvent> DeviceManager::scan() {
  std::vector<DeviceEvent> events;
  const Nanoseconds now = clock_.now();
  auto emit = [&](DeviceEventKind kind, const DeviceDescriptor& device, std::string message) {
    events.push_back(DeviceEvent{kind, device, now, std::move(message)});
  };
  for (auto& [path, entry] : entries_) {
    if (entry.driver && !entry.driver->is_open()) {
      emit(DeviceEventKind::Disconnected, entry.driver->descriptor(), "transport lost");
      entry.driver.reset();
    }
  }
  std::vector<std::pair<DeviceDescriptor, DeviceSource*>> listed;
  for (DeviceSource* source : sources_) {
    std::vector<DeviceDescriptor> devices;
    try {
      devices = source->enumerate();
    } catch (const DeviceError&) {
      continue;  // a source that cannot list now is tried again next scan
    }
    for (auto& device : devices)
      listed.emplace_back(std::move(device), source);
  }
  for (auto it = entries_.begin(); it != entries_.end();) {
    const bool present = std::any_of(listed.begin(), listed.end(), [&](const auto& l) {
      return l.first.path == it->first && l.second == it->second.source;
    });
    if (present) {
      ++it;
      continue;
    }
    if (it->second.driver) {
      it->second.driver->close();
      emit(DeviceEventKind::Disconnected, it->second.driver->descriptor(), "no longer listed");
    }
    emit(DeviceEventKind::Removed, it->second.device, "");
    it = entries_.erase(it);
  }
  for (auto& [device, source] : listed) {
    auto [it, inserted] = entries_.try_emplace(device.path);
    Entry& entry = it->second;
    if (inserted) {
      entry.device = device;
      entry.source = source;
      emit(DeviceEventKind::Arrived, device, "");
    }
    if (entry.driver || entry.failed) continue;
    try {
      entry.driver = registry_.open(source->open(device), clock_);
      entry.order = next_order_++;
      const bool again = !opened_before_.insert(device.path).second;
      emit(again ? DeviceEventKind::Reconnected : DeviceEventKind::Opened,
           entry.driver->descriptor(), entry.driver->driver_name());
    } catch (const DeviceError& error) {
      entry.failed = true;
      emit(DeviceEventKind::OpenFailed, device, error.what());
    }
  }
  return events;
}

std::vector<Device*> DeviceManager::devices() const {
  std::vector<const Entry*> open;
  for (const auto& [path, entry] : entries_) {
    if (entry.driver && entry.driver->is_open()) open.push_back(&entry);
  }
  std::sort(open.begin(), open.end(),
            [](const Entry* a, const Entry* b) { return a->order < b->order; });
  std::vector<Device*> out;
  for (const Entry* entry : open)
    out.push_back(entry->driver.get());
  return out;
}

Device* DeviceManager::find(const std::string& path) const {
  auto it = entries_.find(path);
  if (it == entries_.end() || !it->second.driver || !it->second.driver->is_open()) return nullptr;
  return it->second.driver.get();
}

}  // namespace bisturi::devices
