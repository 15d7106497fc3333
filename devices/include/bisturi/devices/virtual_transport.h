// An in-memory transport pair: the host side is what a driver reads and writes, the device side is
// what a simulated twin (or a trace player) reads and writes. Thread-safe queues, disconnect
// simulation. A VirtualBus lists virtual devices and opens pairs to them (hot-plug in tests).
#pragma once

#include <chrono>
#include <cstddef>
#include <functional>
#include <memory>
#include <mutex>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/transport.h"

namespace bisturi::devices {

namespace detail {
struct VirtualLink;
}

struct VirtualPair;
class VirtualTransport;
VirtualPair make_virtual_pair(DeviceDescriptor descriptor, std::size_t queue_capacity = 4096);

class VirtualTransport final : public Transport {
 public:
  enum class Side : std::uint8_t { Host, Device };

  ~VirtualTransport() override;
  const DeviceDescriptor& descriptor() const override;
  // Host side: input reports the device side wrote. Device side: output reports the host wrote.
  std::optional<Bytes> read(std::chrono::microseconds timeout) override;
  bool read_into(Bytes& report, std::chrono::microseconds timeout) override;
  void write(std::span<const std::uint8_t> report) override;
  // Host side: the report goes to the device side ahead of the queue, past a write() in
  // progress (up to 4 waiting, 64 bytes each). The device side reads it before queued ones.
  bool write_preempting(std::span<const std::uint8_t> report) noexcept override;
  // Either side: the host's next write() blocks for `duration` first, as a device that holds
  // off its endpoint makes it (fault injection).
  void stall_next_host_write(std::chrono::nanoseconds duration);

  Side side() const { return side_; }
  // Breaks the link for both sides: reads and writes then throw DeviceDisconnected (queued
  // reports are dropped, as a real unplug loses them). Idempotent.
  void disconnect();
  bool connected() const;
  // Reports waiting to be read on this side.
  std::size_t pending() const;
  // Reports dropped because this side's queue was full (oldest go first).
  std::size_t dropped() const;
  // Called (on the writer's thread) after each report the other side writes towards this side.
  // Lets a twin answer at once instead of polling. Pass nullptr to remove.
  void set_on_report(std::function<void()> callback);

 private:
  friend class VirtualBus;
  friend VirtualPair make_virtual_pair(DeviceDescriptor, std::size_t);
  VirtualTransport(std::shared_ptr<detail::VirtualLink> link, Side side);
  std::shared_ptr<detail::VirtualLink> link_;
  Side side_;
};

struct VirtualPair {
  std::unique_ptr<VirtualTransport> host;
  std::unique_ptr<VirtualTransport> device;
};

// descriptor.kind is set to Virtual unless it is Hid or Usb already (a twin of a HID device keeps
// Hid so the same driver matches). queue_capacity: reports each direction holds before dropping.
VirtualPair make_virtual_pair(DeviceDescriptor descriptor, std::size_t queue_capacity);

// A bus of virtual devices, polled like hidapi/libusb enumeration.
class VirtualBus final : public DeviceSource {
 public:
  // Receives the device side when the host opens the device.
  using Connector = std::function<void(std::unique_ptr<VirtualTransport> device_side)>;

  // Plugs a device in (its path must be unique on the bus; std::invalid_argument otherwise).
  void plug(DeviceDescriptor device, Connector on_open);
  // Unplugs it: open links are disconnected and it is no longer enumerated. Unknown path: no-op.
  void unplug(const std::string& path);

  std::vector<DeviceDescriptor> enumerate() override;
  // Throws DeviceError when the device is not plugged in.
  std::unique_ptr<Transport> open(const DeviceDescriptor& device) override;

 private:
  struct Slot {
    DeviceDescriptor device;
    Connector on_open;
    std::vector<std::weak_ptr<detail::VirtualLink>> links;
  };
  std::mutex mutex_;
  std::vector<Slot> slots_;
};

}  // namespace bisturi::devices
