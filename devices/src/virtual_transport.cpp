#include "bisturi/devices/virtual_transport.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <condition_variable>
#include <cstring>
#include <stdexcept>
#include <thread>

namespace bisturi::devices {

namespace detail {

/// A FIFO of reports that keeps its buffers: a report written is copied into a slot's buffer
/// (reusing its storage) and read_into() swaps the reader's buffer into the slot, so a steady
/// stream allocates nothing once each slot has held a report. It grows (allocates) only when
/// more reports wait than ever before.
class ReportQueue {
 public:
  [[nodiscard]] bool empty() const { return count_ == 0; }
  [[nodiscard]] std::size_t size() const { return count_; }
  void clear() { head_ = count_ = 0; }
  Bytes& front() { return slots_[head_]; }
  void pop_front() {
    head_ = (head_ + 1) % slots_.size();
    --count_;
  }
  void push_back(std::span<const std::uint8_t> report) {
    if (count_ == slots_.size()) {
      std::rotate(slots_.begin(), slots_.begin() + static_cast<std::ptrdiff_t>(head_),
                  slots_.end());
      head_ = 0;
      slots_.resize(std::max<std::size_t>(8, 2 * slots_.size()));
    }
    slots_[(head_ + count_) % slots_.size()].assign(report.begin(), report.end());
    ++count_;
  }

 private:
  std::vector<Bytes> slots_;
  std::size_t head_ = 0, count_ = 0;
};

/// Reports written past the queue and its lock (write_preempting): a few fixed slots, each
/// claimed, filled and published by atomics, taken by the reader before anything queued.
class PreemptingSlots {
 public:
  static constexpr std::size_t kSlots = 4, kBytes = 64;
  bool put(std::span<const std::uint8_t> report) noexcept {
    if (report.size() > kBytes) return false;
    for (std::size_t i = 0; i < kSlots; ++i) {
      std::uint32_t free = kFree;
      if (!state_[i].compare_exchange_strong(free, kFilling, std::memory_order_acquire)) continue;
      std::memcpy(bytes_[i].data(), report.data(), report.size());
      size_[i] = report.size();
      order_[i] = next_order_.fetch_add(1, std::memory_order_relaxed);
      state_[i].store(kReady, std::memory_order_release);
      return true;
    }
    return false;
  }
  [[nodiscard]] bool any() const {
    for (const auto& s : state_)
      if (s.load(std::memory_order_acquire) == kReady) return true;
    return false;
  }
  /// The oldest ready report into `out`; false when none.
  bool take(Bytes& out) {
    std::size_t best = kSlots;
    for (std::size_t i = 0; i < kSlots; ++i) {
      if (state_[i].load(std::memory_order_acquire) != kReady) continue;
      if (best == kSlots || order_[i] < order_[best]) best = i;
    }
    if (best == kSlots) return false;
    out.assign(bytes_[best].begin(),
               bytes_[best].begin() + static_cast<std::ptrdiff_t>(size_[best]));
    state_[best].store(kFree, std::memory_order_release);
    return true;
  }

 private:
  static constexpr std::uint32_t kFree = 0, kFilling = 1, kReady = 2;
  std::array<std::atomic<std::uint32_t>, kSlots> state_{};
  std::array<std::array<std::uint8_t, kBytes>, kSlots> bytes_{};
  std::array<std::size_t, kSlots> size_{};
  std::array<std::uint64_t, kSlots> order_{};
  std::atomic<std::uint64_t> next_order_{0};
};

struct VirtualLink {
  DeviceDescriptor descriptor;
  std::size_t capacity = 0;
  mutable std::mutex mutex;
  std::condition_variable changed;
  bool connected = true;
  // queue[0]: towards the host (input reports), queue[1]: towards the device (output reports).
  ReportQueue queue[2];
  std::size_t dropped[2] = {0, 0};
  std::function<void()> on_report[2];
  // Towards the device only: output reports a stuck host write must not hold up.
  PreemptingSlots preempting;
  std::atomic<std::int64_t> stall_next_host_write_ns{0};
  // on_report[1] while the device side has one: a pre-empting write calls it without the lock.
  std::atomic<const std::function<void()>*> device_listener{nullptr};
};

}  // namespace detail

namespace {
int inbox(VirtualTransport::Side side) {
  return side == VirtualTransport::Side::Host ? 0 : 1;
}
}  // namespace

VirtualTransport::VirtualTransport(std::shared_ptr<detail::VirtualLink> link, Side side)
    : link_(std::move(link)), side_(side) {}

VirtualTransport::~VirtualTransport() = default;

const DeviceDescriptor& VirtualTransport::descriptor() const {
  return link_->descriptor;
}

std::optional<Bytes> VirtualTransport::read(std::chrono::microseconds timeout) {
  Bytes report;
  if (!read_into(report, timeout)) return std::nullopt;
  return report;
}

bool VirtualTransport::read_into(Bytes& report, std::chrono::microseconds timeout) {
  auto& link = *link_;
  std::unique_lock lock(link.mutex);
  auto& queue = link.queue[inbox(side_)];
  const bool device_side = side_ == Side::Device;
  auto ready = [&] {
    return !link.connected || !queue.empty() || (device_side && link.preempting.any());
  };
  if (!ready()) {
    if (timeout.count() <= 0) return false;
    if (!link.changed.wait_for(lock, timeout, ready)) return false;
  }
  if (!link.connected) {
    throw DeviceDisconnected(describe(link.descriptor) + ": disconnected");
  }
  if (device_side && link.preempting.take(report)) return true;
  std::swap(report, queue.front());  // the reader's old buffer stays for the next report
  queue.pop_front();
  return true;
}

void VirtualTransport::write(std::span<const std::uint8_t> report) {
  auto& link = *link_;
  const int target = 1 - inbox(side_);
  if (side_ == Side::Host) {
    // A stalled device: the write returns only when the stall is over.
    const std::int64_t stall_ns = link.stall_next_host_write_ns.exchange(0);
    if (stall_ns > 0) std::this_thread::sleep_for(std::chrono::nanoseconds(stall_ns));
  }
  std::function<void()> callback;
  {
    std::lock_guard lock(link.mutex);
    if (!link.connected) {
      throw DeviceDisconnected(describe(link.descriptor) + ": disconnected");
    }
    auto& queue = link.queue[target];
    if (queue.size() >= link.capacity) {
      queue.pop_front();
      ++link.dropped[target];
    }
    queue.push_back(report);
    callback = link.on_report[target];
  }
  link.changed.notify_all();
  if (callback) callback();
}

bool VirtualTransport::write_preempting(std::span<const std::uint8_t> report) noexcept {
  if (side_ != Side::Host || !link_->preempting.put(report)) return false;
  // The report has left the host. What follows is the device's side taking it: a twin's
  // listener (under the twin's own lock, the simulated hardware's) or a reader woken here.
  link_->changed.notify_all();
  if (const std::function<void()>* listener = link_->device_listener.load()) {
    try {
      (*listener)();
    } catch (...) {  // the device's trouble, not the sender's: the report is delivered
    }
  }
  return true;
}

void VirtualTransport::stall_next_host_write(std::chrono::nanoseconds duration) {
  link_->stall_next_host_write_ns.store(duration.count());
}

void VirtualTransport::disconnect() {
  {
    std::lock_guard lock(link_->mutex);
    link_->connected = false;
    link_->queue[0].clear();
    link_->queue[1].clear();
  }
  link_->changed.notify_all();
}

bool VirtualTransport::connected() const {
  std::lock_guard lock(link_->mutex);
  return link_->connected;
}

std::size_t VirtualTransport::pending() const {
  std::lock_guard lock(link_->mutex);
  return link_->queue[inbox(side_)].size();
}

std::size_t VirtualTransport::dropped() const {
  std::lock_guard lock(link_->mutex);
  return link_->dropped[inbox(side_)];
}

void VirtualTransport::set_on_report(std::function<void()> callback) {
  std::lock_guard lock(link_->mutex);
  const int box = inbox(side_);
  if (side_ == Side::Device) link_->device_listener.store(nullptr);
  link_->on_report[box] = std::move(callback);
  if (side_ == Side::Device && link_->on_report[box])
    link_->device_listener.store(&link_->on_report[box]);
}

VirtualPair make_virtual_pair(DeviceDescriptor descriptor, std::size_t queue_capacity) {
  auto link = std::make_shared<detail::VirtualLink>();
  link->descriptor = std::move(descriptor);
  link->capacity = std::max<std::size_t>(queue_capacity, 1);
  VirtualPair pair;
  pair.host.reset(new VirtualTransport(link, VirtualTransport::Side::Host));
  pair.device.reset(new VirtualTransport(link, VirtualTransport::Side::Device));
  return pair;
}

void VirtualBus::plug(DeviceDescriptor device, Connector on_open) {
  std::lock_guard lock(mutex_);
  for (const auto& slot : slots_) {
    if (slot.device.path == device.path) {
      throw std::invalid_argument("virtual bus: path already plugged in: " + device.path);
    }
  }
  slots_.push_back(Slot{std::move(device), std::move(on_open), {}});
}

void VirtualBus::unplug(const std::string& path) {
  std::vector<std::shared_ptr<detail::VirtualLink>> links;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(slots_.begin(), slots_.end(),
                           [&](const Slot& slot) { return slot.device.path == path; });
    if (it == slots_.end()) return;
    for (auto& weak : it->links) {
      if (auto link = weak.lock()) links.push_back(std::move(link));
    }
    slots_.erase(it);
  }
  for (auto& link : links) {
    {
      std::lock_guard lock(link->mutex);
      link->connected = false;
      link->queue[0].clear();
      link->queue[1].clear();
    }
    link->changed.notify_all();
  }
}

std::vector<DeviceDescriptor> VirtualBus::enumerate() {
  std::lock_guard lock(mutex_);
  std::vector<DeviceDescriptor> out;
  out.reserve(slots_.size());
  for (const auto& slot : slots_)
    out.push_back(slot.device);
  return out;
}

std::unique_ptr<Transport> VirtualBus::open(const DeviceDescriptor& device) {
  Connector connector;
  VirtualPair pair;
  {
    std::lock_guard lock(mutex_);
    auto it = std::find_if(slots_.begin(), slots_.end(),
                           [&](const Slot& slot) { return slot.device.path == device.path; });
    if (it == slots_.end()) {
      throw DeviceError(describe(device) + ": not plugged in");
    }
    pair = make_virtual_pair(it->device);
    it->links.erase(std::remove_if(it->links.begin(), it->links.end(),
                                   [](const auto& weak) { return weak.expired(); }),
                    it->links.end());
    it->links.push_back(pair.host->link_);
    connector = it->on_open;
  }
  if (connector) connector(std::move(pair.device));
  return std::unique_ptr<Transport>(std::move(pair.host));
}

}  // namespace bisturi::devices
