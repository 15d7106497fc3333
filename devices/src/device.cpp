#include "bisturi/devices/device.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "bisturi/devices/transport.h"

namespace bisturi::devices {

const char* to_string(DeviceClass device_class) {
  switch (device_class) {
    case DeviceClass::HapticGlove:
      return "haptic-glove";
    case DeviceClass::HapticArm:
      return "haptic-arm";
    case DeviceClass::HeadTracker:
      return "head-tracker";
  }
  return "unknown";
}

const char* to_string(DeviceEventKind kind) {
  switch (kind) {
    case DeviceEventKind::Arrived:
      return "arrived";
    case DeviceEventKind::Opened:
      return "opened";
    case DeviceEventKind::Disconnected:
      return "disconnected";
    case DeviceEventKind::Reconnected:
      return "reconnected";
    case DeviceEventKind::Removed:
      return "removed";
    case DeviceEventKind::OpenFailed:
      return "open-failed";
  }
  return "unknown";
}

std::size_t Capabilities::force_components() const {
  std::size_t n = 0;
  for (const auto& channel : force_channels)
    n += channel.components;
  return n;
}

Device::Device(std::unique_ptr<Transport> transport, Clock& clock)
    : transport_(std::move(transport)), clock_(&clock) {}

Device::~Device() = default;

Transport& Device::transport() {
  if (!transport_) throw DeviceDisconnected(driver_name() + ": device is closed");
  return *transport_;
}

void Device::close() {
  if (!transport_) return;
  try {
    send_zero();
  } catch (...) {
    // Gone already: nothing to stop.
  }
  transport_.reset();
}

void Device::prepare_preempting_zero() {
  zero_reports(preempting_zero_);
}

bool Device::send_zero_preempting() noexcept {
  if (transport_ == nullptr || preempting_zero_.empty()) return false;
  for (const Bytes& report : preempting_zero_)
    if (!transport_->write_preempting(report)) return false;
  return true;
}

std::size_t Device::poll_transport(std::chrono::microseconds timeout) {
  // Only the first read may wait, and only when the caller asked: poll(0) never waits, and after
  // the first report the rest are taken only if they are already there.
  std::size_t handled = 0;
  auto wait = std::max(timeout, std::chrono::microseconds(0));
  for (;;) {
    bool got = false;
    try {
      got = transport().read_into(report_, wait);
    } catch (const DeviceDisconnected&) {
      transport_.reset();
      throw;
    }
    if (!got) break;
    handle_report(report_);
    ++handled;
    wait = std::chrono::microseconds(0);
  }
  return handled;
}

double force_extent(const ForceChannel& channel, const double* force_N) {
  double sum = 0.0, largest = 0.0;
  for (std::size_t i = 0; i < channel.components; ++i) {
    sum += force_N[i] * force_N[i];
    largest = std::max(largest, std::abs(force_N[i]));
  }
  return channel.per_axis ? largest : std::sqrt(sum);
}

HapticDevice* as_haptic(Device* device) {
  return dynamic_cast<HapticDevice*>(device);
}
Tracker* as_tracker(Device* device) {
  return dynamic_cast<Tracker*>(device);
}

void HapticDevice::expect_force_values(std::span<const double> forces_N, std::size_t count) const {
  if (forces_N.size() != count) {
    throw std::invalid_argument(describe(descriptor()) + ": expected " + std::to_string(count) +
                                " force values, got " + std::to_string(forces_N.size()));
  }
}

}  // namespace bisturi::devices
