#include <algorithm>
#include <cmath>

#include "bisturi/devices/simulated.h"

namespace bisturi::devices {

namespace {

Quaternion nlerp(const Quaternion& a, Quaternion b, double s) {
  const double dot = a.w * b.w + a.x * b.x + a.y * b.y + a.z * b.z;
  if (dot < 0) b = {-b.w, -b.x, -b.y, -b.z};
  Quaternion q{a.w + (b.w - a.w) * s, a.x + (b.x - a.x) * s, a.y + (b.y - a.y) * s,
               a.z + (b.z - a.z) * s};
  const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
  if (n < 1e-12) return a;
  return {q.w / n, q.x / n, q.y / n, q.z / n};
}

// The keys around t and the blend between them.
template <typename F>
void at_time(const std::vector<MotionKey>& keys, Nanoseconds t, F&& f) {
  if (keys.empty()) return;
  if (t <= keys.front().t) return f(keys.front(), keys.front(), 0.0);
  if (t >= keys.back().t) return f(keys.back(), keys.back(), 0.0);
  auto next = std::upper_bound(keys.begin(), keys.end(), t,
                               [](Nanoseconds v, const MotionKey& k) { return v < k.t; });
  const MotionKey& b = *next;
  const MotionKey& a = *(next - 1);
  const double span = static_cast<double>((b.t - a.t).count());
  f(a, b, span > 0 ? static_cast<double>((t - a.t).count()) / span : 0.0);
}

}  // namespace

Pose DeviceScript::pose_at(Nanoseconds t) const {
  Pose pose;
  at_time(motion, t, [&](const MotionKey& a, const MotionKey& b, double s) {
    pose.position_m = {a.pose.position_m.x + (b.pose.position_m.x - a.pose.position_m.x) * s,
                       a.pose.position_m.y + (b.pose.position_m.y - a.pose.position_m.y) * s,
                       a.pose.position_m.z + (b.pose.position_m.z - a.pose.position_m.z) * s};
    pose.orientation = nlerp(a.pose.orientation, b.pose.orientation, s);
  });
  return pose;
}

std::vector<double> DeviceScript::joints_at(Nanoseconds t, std::size_t joints) const {
  std::vector<double> out(joints, 0.0);
  at_time(motion, t, [&](const MotionKey& a, const MotionKey& b, double s) {
    for (std::size_t j = 0; j < joints; ++j) {
      const double ja = j < a.joints_rad.size() ? a.joints_rad[j] : 0.0;
      const double jb = j < b.joints_rad.size() ? b.joints_rad[j] : 0.0;
      out[j] = ja + (jb - ja) * s;
    }
  });
  for (const auto& contact : contacts) {
    if (t >= contact.begin && t < contact.end && contact.joint < joints) {
      out[contact.joint] = std::min(out[contact.joint], contact.max_angle_rad);
    }
  }
  return out;
}

std::uint64_t DeviceScript::buttons_at(Nanoseconds t) const {
  std::uint64_t buttons = 0;
  for (const auto& press : presses) {  // in script order
    if (press.t > t || press.button >= 64) continue;
    const std::uint64_t mask = std::uint64_t{1} << press.button;
    buttons = press.down ? (buttons | mask) : (buttons & ~mask);
  }
  return buttons;
}

SimulatedDevice::SimulatedDevice(DeviceDescriptor descriptor, Nanoseconds period)
    : descriptor_(std::move(descriptor)), period_(period) {}

SimulatedDevice::~SimulatedDevice() {
  std::lock_guard lock(mutex_);
  if (link_) link_->set_on_report(nullptr);
}

void SimulatedDevice::attach(std::unique_ptr<VirtualTransport> device_side) {
  std::lock_guard lock(mutex_);
  if (link_) link_->set_on_report(nullptr);
  link_ = std::move(device_side);
  have_sent_ = false;
  if (link_) link_->set_on_report([this] { drain(); });
}

VirtualBus::Connector SimulatedDevice::connector() {
  return [this](std::unique_ptr<VirtualTransport> device_side) { attach(std::move(device_side)); };
}

void SimulatedDevice::disconnect() {
  std::lock_guard lock(mutex_);
  if (link_) link_->disconnect();
}

void SimulatedDevice::stall_host_writes(Nanoseconds duration) {
  std::lock_guard lock(mutex_);
  if (link_) link_->stall_next_host_write(duration);
}

bool SimulatedDevice::attached() const {
  std::lock_guard lock(mutex_);
  return link_ && link_->connected();
}

void SimulatedDevice::drain() {
  std::lock_guard lock(mutex_);
  if (!link_) return;
  try {
    while (link_->read_into(output_, std::chrono::microseconds(0))) {
      ++outputs_;
      on_output(output_);
    }
  } catch (const DeviceDisconnected&) {
  }
}

bool SimulatedDevice::step(Nanoseconds t) {
  std::lock_guard lock(mutex_);
  if (!link_ || !link_->connected()) return false;
  if (have_sent_ && t < next_) return false;
  next_ = have_sent_ ? next_ + period_ : t + period_;
  if (next_ <= t) next_ = t + period_;  // fell behind: no burst
  have_sent_ = true;
  const Bytes report = input_report(t);
  try {
    link_->write(report);
  } catch (const DeviceDisconnected&) {
    return false;
  }
  return true;
}

std::uint64_t SimulatedDevice::outputs_received() const {
  std::lock_guard lock(mutex_);
  return outputs_;
}

void SimulatedDevice::send_locked(std::span<const std::uint8_t> report) {
  if (!link_) return;
  try {
    link_->write(report);
  } catch (const DeviceDisconnected&) {
  }
}

}  // namespace bisturi::devices
