#include "bisturi/devices/trace/replay_transport.h"

#include <utility>

namespace bisturi::devices {

void ReplayLink::push_input(Nanoseconds time, std::span<const std::uint8_t> report) {
  std::lock_guard lock(mutex_);
  inputs_.push_back(Input{time, Bytes(report.begin(), report.end())});
}

std::size_t ReplayLink::pending() const {
  std::lock_guard lock(mutex_);
  return inputs_.size();
}

void ReplayLink::disconnect() {
  std::lock_guard lock(mutex_);
  connected_ = false;
  inputs_.clear();
}

bool ReplayLink::connected() const {
  std::lock_guard lock(mutex_);
  return connected_;
}

std::vector<CapturedReport> ReplayLink::take_written() {
  std::lock_guard lock(mutex_);
  return std::exchange(written_, {});
}

ReplayTransport::ReplayTransport(DeviceDescriptor descriptor, Clock& clock)
    : descriptor_(std::move(descriptor)), clock_(&clock), link_(std::make_shared<ReplayLink>()) {}

ReplayTransport::ReplayTransport(DeviceDescriptor descriptor, Clock& clock,
                                 std::shared_ptr<ReplayLink> link)
    : descriptor_(std::move(descriptor)), clock_(&clock), link_(std::move(link)) {}

std::optional<Bytes> ReplayTransport::read(std::chrono::microseconds timeout) {
  std::unique_lock lock(link_->mutex_);
  if (!link_->connected_) {
    throw DeviceDisconnected(describe(descriptor_) + ": disconnected (replay)");
  }
  const Nanoseconds now = clock_->now();
  const Nanoseconds deadline = now + std::chrono::duration_cast<Nanoseconds>(timeout);
  auto& inputs = link_->inputs_;
  if (!inputs.empty() && inputs.front().time <= deadline) {
    const Nanoseconds due = inputs.front().time;
    Bytes report = std::move(inputs.front().bytes);
    inputs.pop_front();
    lock.unlock();
    if (due > now) clock_->sleep_until(due);
    return report;
  }
  lock.unlock();
  if (timeout.count() > 0) clock_->sleep_until(deadline);
  return std::nullopt;
}

void ReplayTransport::write(std::span<const std::uint8_t> report) {
  std::lock_guard lock(link_->mutex_);
  if (!link_->connected_) {
    throw DeviceDisconnected(describe(descriptor_) + ": disconnected (replay)");
  }
  link_->written_.push_back(CapturedReport{clock_->now(), Bytes(report.begin(), report.end())});
}

}  // namespace bisturi::devices
