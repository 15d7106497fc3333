// The openxr-controller driver and its feed (see openxr_controller.h).
#include "bisturi/devices/controller/openxr_controller.h"

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <stdexcept>

namespace bisturi::devices {

namespace {

namespace cp = controller_protocol;

void put_u32(Bytes& b, std::size_t at, std::uint32_t v) {
  for (std::size_t i = 0; i < 4; ++i)
    b[at + i] = static_cast<std::uint8_t>(v >> (8 * i));
}
void put_f32(Bytes& b, std::size_t at, double v) {
  put_u32(b, at, std::bit_cast<std::uint32_t>(static_cast<float>(v)));
}
std::uint32_t get_u32(std::span<const std::uint8_t> b, std::size_t at) {
  std::uint32_t v = 0;
  for (std::size_t i = 0; i < 4; ++i)
    v |= static_cast<std::uint32_t>(b[at + i]) << (8 * i);
  return v;
}
double get_f32(std::span<const std::uint8_t> b, std::size_t at) {
  return static_cast<double>(std::bit_cast<float>(get_u32(b, at)));
}

DeviceDescriptor feed_descriptor() {
  DeviceDescriptor d;
  d.kind = TransportKind::Virtual;
  d.product = "OpenXR right-hand controller";
  d.path = "openxr:/user/hand/right";
  d.driver = kOpenXrControllerDriver;
  return d;
}

class OpenXrController final : public HapticDevice {
 public:
  OpenXrController(std::unique_ptr<Transport> transport, Clock& clock)
      : HapticDevice(std::move(transport), clock), descriptor_(Device::transport().descriptor()) {
    descriptor_.driver = kOpenXrControllerDriver;
    caps_.device_class = DeviceClass::HapticGlove;
    caps_.end_effectors = 1;
    caps_.buttons = 1;
    caps_.force_channels = {
        ForceChannel{"vibration", 1, cp::kMaxForceN, cp::kMaxForceRateNPerS, false}};
    state_.end_effector_poses.resize(1);
  }
  ~OpenXrController() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const HapticState& state() const override { return state_; }
  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> p) override {
    const std::string device = describe(descriptor_);
    if (p.size() != cp::kInputSize)
      throw ProtocolError(device, p.size(),
                          "report of " + std::to_string(p.size()) + " bytes, expected 44");
    if (p[0] != cp::kState)
      throw ProtocolError(device, 0, "unknown report type " + std::to_string(p[0]));
    if ((p[1] & ~cp::kActive) != 0) throw ProtocolError(device, 1, "unknown flag bits");
    if (p[2] != 0 || p[3] != 0) throw ProtocolError(device, 2, "reserved bytes not zero");
    std::array<double, 8> v{};
    for (std::size_t i = 0; i < v.size(); ++i) {
      v[i] = get_f32(p, 12 + 4 * i);
      if (!std::isfinite(v[i])) throw ProtocolError(device, 12 + 4 * i, "not a finite number");
    }
    const double norm = std::sqrt(v[3] * v[3] + v[4] * v[4] + v[5] * v[5] + v[6] * v[6]);
    if (std::abs(norm - 1.0) > 1e-3)
      throw ProtocolError(device, 24, "orientation is not a unit quaternion");
    if (v[7] < 0.0 || v[7] > 1.0) throw ProtocolError(device, 40, "trigger outside 0..1");
    // An inactive controller keeps its last pose (the runtime lost it): only the trigger counts.
    state_.tracked = (p[1] & cp::kActive) != 0;
    if (state_.tracked) {
      Pose& pose = state_.end_effector_poses[0];
      pose.position_m = {v[0], v[1], v[2]};
      pose.orientation = {v[6] / norm, v[3] / norm, v[4] / norm, v[5] / norm};
    }
    state_.buttons = v[7] > cp::kTriggerPressed ? 1u : 0u;
    ++state_.reports;
    state_.sample_time = clock().now();
  }

  void send_forces(std::span<const double> forces_N) override {
    if (forces_N.size() != 1)
      throw std::invalid_argument(describe(descriptor_) + ": expected 1 force value, got " +
                                  std::to_string(forces_N.size()));
    const double f = std::abs(forces_N[0]);
    const double amplitude = std::isfinite(f) ? std::clamp(f / cp::kMaxForceN, 0.0, 1.0) : 0.0;
    Bytes out(cp::kOutputSize, 0);
    out[0] = cp::kVibration;
    out[1] = sequence_++;
    put_f32(out, 4, amplitude);
    transport().write(out);
  }

 private:
  void send_zero() override {
    const double zero[1] = {0.0};
    send_forces(zero);
  }

  std::string name_ = kOpenXrControllerDriver;
  DeviceDescriptor descriptor_;
  Capabilities caps_;
  HapticState state_;
  std::uint8_t sequence_ = 0;
};

}  // namespace

Bytes encode_controller_report(const ControllerSample& s) {
  Bytes b(cp::kInputSize, 0);
  b[0] = cp::kState;
  b[1] = s.active ? cp::kActive : 0;
  const auto t = static_cast<std::uint64_t>(s.t_ns);
  put_u32(b, 4, static_cast<std::uint32_t>(t & 0xFFFFFFFFu));
  put_u32(b, 8, static_cast<std::uint32_t>(t >> 32));
  put_f32(b, 12, s.position_m.x);
  put_f32(b, 16, s.position_m.y);
  put_f32(b, 20, s.position_m.z);
  put_f32(b, 24, s.orientation.x);
  put_f32(b, 28, s.orientation.y);
  put_f32(b, 32, s.orientation.z);
  put_f32(b, 36, s.orientation.w);
  put_f32(b, 40, std::clamp(s.trigger, 0.0, 1.0));
  return b;
}

std::optional<double> decode_vibration_report(std::span<const std::uint8_t> r) {
  if (r.size() != cp::kOutputSize || r[0] != cp::kVibration || r[2] != 0 || r[3] != 0)
    return std::nullopt;
  const double a = get_f32(r, 4);
  if (!(a >= 0.0 && a <= 1.0)) return std::nullopt;
  return a;
}

std::unique_ptr<Transport> ControllerFeed::open() {
  std::lock_guard lock(mutex_);
  if (device_side_) return nullptr;
  VirtualPair pair = make_virtual_pair(feed_descriptor());
  device_side_ = std::move(pair.device);
  return std::move(pair.host);
}

std::unique_ptr<Transport> ControllerFeed::open_for(const DriverInfo& driver) {
  return driver.name == kOpenXrControllerDriver ? open() : nullptr;
}

bool ControllerFeed::opened() const {
  std::lock_guard lock(mutex_);
  return device_side_ != nullptr;
}

void ControllerFeed::push(const ControllerSample& sample) {
  std::lock_guard lock(mutex_);
  if (!device_side_ || !device_side_->connected()) return;
  device_side_->write(encode_controller_report(sample));
}

std::optional<double> ControllerFeed::take_vibration() {
  std::lock_guard lock(mutex_);
  if (!device_side_ || !device_side_->connected()) return std::nullopt;
  std::optional<double> newest;
  while (std::optional<Bytes> r = device_side_->read(std::chrono::microseconds(0))) {
    if (std::optional<double> a = decode_vibration_report(*r)) {
      newest = a;
    } else {
      ++rejected_;
    }
  }
  return newest;
}

std::uint64_t ControllerFeed::rejected() const {
  std::lock_guard lock(mutex_);
  return rejected_;
}

std::unique_ptr<HapticDevice> open_openxr_controller(std::unique_ptr<Transport> transport,
                                                     Clock& clock) {
  if (!transport) throw std::invalid_argument("open_openxr_controller: no transport");
  return std::make_unique<OpenXrController>(std::move(transport), clock);
}

DriverInfo openxr_controller_driver_info() {
  DriverInfo info;
  info.name = kOpenXrControllerDriver;
  info.summary = "OpenXR hand controller: grip pose, trigger as button 0, vibration as the cue";
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_openxr_controller(std::move(transport), clock);
  };
  info.bus = TransportKind::Virtual;  // fed by the render thread's OpenXR sink, never enumerated
  info.device_class = DeviceClass::HapticGlove;
  info.layout.channels = {ChannelRole{ChannelUse::Finger, 0}};
  return info;
}

}  // namespace bisturi::devices
