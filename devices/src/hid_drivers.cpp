#include "bisturi/devices/hid_drivers.h"

#include <cstdio>
#include <stdexcept>

#include "bisturi/devices/simulated.h"
#include "hid_mapping.h"

namespace bisturi::devices {

namespace {

DeviceDescriptor with_driver(DeviceDescriptor device, const char* driver) {
  device.driver = driver;
  return device;
}

class HidGlove final : public HapticDevice {
 public:
  HidGlove(std::unique_ptr<Transport> transport, Clock& clock, HidGloveOptions options)
      : HapticDevice(std::move(transport), clock),
        descriptor_(with_driver(Device::transport().descriptor(), kHidGloveDriver)),
        mapping_(descriptor_, options.max_force_rate_N_per_s),
        caps_(mapping_.capabilities()) {
    caps_.spec.max_stiffness_N_per_m = options.max_stiffness_N_per_m;
    const auto& caps = caps_;
    if (caps.finger_joints.empty() && !mapping_.has_pose() && caps.buttons == 0) {
      throw ProtocolError(describe(descriptor_), 0,
                          "the report descriptor describes no finger joints, pose or buttons");
    }
    state_.end_effector_poses.resize(caps.end_effectors);
    state_.finger_joint_angles_rad.assign(caps.finger_joints.size(), 0.0);
    zeros_.assign(caps.force_components(), 0.0);
  }
  ~HidGlove() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const HapticState& state() const override { return state_; }

  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> report) override {
    Pose* pose = state_.end_effector_poses.empty() ? nullptr : &state_.end_effector_poses[0];
    if (mapping_.apply(report, pose, &state_.finger_joint_angles_rad, &state_.buttons)) {
      ++state_.reports;
      state_.sample_time = clock().now();
    }
  }

  void send_forces(std::span<const double> forces_N) override {
    expect_force_values(forces_N, zeros_.size());
    mapping_.encode_forces(forces_N, reports_);
    for (const auto& report : reports_)
      transport().write(report);
  }

 private:
  void send_zero() override {
    if (!zeros_.empty()) send_forces(zeros_);
  }
  void zero_reports(std::vector<Bytes>& out) const override {
    out.clear();
    if (!zeros_.empty()) mapping_.encode_forces(zeros_, out);
  }

  std::string name_ = kHidGloveDriver;
  DeviceDescriptor descriptor_;
  detail::HidMapping mapping_;
  Capabilities caps_;
  HapticState state_;
  std::vector<double> zeros_;
  std::vector<Bytes> reports_;
};

class HidTracker final : public Tracker {
 public:
  HidTracker(std::unique_ptr<Transport> transport, Clock& clock)
      : Tracker(std::move(transport), clock),
        descriptor_(with_driver(Device::transport().descriptor(), kHidTrackerDriver)),
        mapping_(descriptor_, 1.0) {
    if (!mapping_.has_pose()) {
      throw ProtocolError(describe(descriptor_), 0, "the report descriptor describes no pose");
    }
    caps_ = mapping_.capabilities();
    caps_.device_class = DeviceClass::HeadTracker;
    caps_.head_pose = true;
    caps_.end_effectors = 0;
    caps_.force_channels.clear();
    caps_.spec.max_stiffness_N_per_m = 0.0;  // renders no force
  }
  ~HidTracker() override { close(); }

  const std::string& driver_name() const override { return name_; }
  const DeviceDescriptor& descriptor() const override { return descriptor_; }
  const Capabilities& capabilities() const override { return caps_; }
  const TrackerState& state() const override { return state_; }

  std::size_t poll(std::chrono::microseconds timeout) override { return poll_transport(timeout); }

  void handle_report(std::span<const std::uint8_t> report) override {
    if (mapping_.apply(report, &state_.head_pose, nullptr, nullptr)) {
      ++state_.reports;
      state_.sample_time = clock().now();
    }
  }

 private:
  std::string name_ = kHidTrackerDriver;
  DeviceDescriptor descriptor_;
  detail::HidMapping mapping_;
  Capabilities caps_;
  TrackerState state_;
};

std::uint32_t application_of(const DeviceDescriptor& device) {
  if (device.report_descriptor.empty()) return 0;
  try {
    return hid::parse_report_descriptor(device.report_descriptor).application_usage();
  } catch (const ProtocolError&) {
    return 0;
  }
}

}  // namespace

std::unique_ptr<HapticDevice> open_hid_glove(std::unique_ptr<Transport> transport, Clock& clock,
                                             HidGloveOptions options) {
  if (!transport) throw std::invalid_argument("open_hid_glove: no transport");
  return std::make_unique<HidGlove>(std::move(transport), clock, options);
}

std::unique_ptr<Tracker> open_hid_tracker(std::unique_ptr<Transport> transport, Clock& clock) {
  if (!transport) throw std::invalid_argument("open_hid_tracker: no transport");
  return std::make_unique<HidTracker>(std::move(transport), clock);
}

bool describes_hid_glove(const DeviceDescriptor& device) {
  return application_of(device) == hid::kUsageGlove;
}

bool describes_hid_tracker(const DeviceDescriptor& device) {
  const auto usage = application_of(device);
  return usage == hid::kUsageHeadTracker || usage == hid::kUsageHeadMountedDisplay;
}

GenericHidFit assess_generic_hid(std::span<const std::uint8_t> report_descriptor) {
  DeviceDescriptor device;
  device.kind = TransportKind::Hid;
  device.product = "HID descriptor";
  device.report_descriptor.assign(report_descriptor.begin(), report_descriptor.end());
  const detail::HidMapping mapping(device, HidGloveOptions{}.max_force_rate_N_per_s);
  const Capabilities& caps = mapping.capabilities();
  GenericHidFit fit;
  if (!caps.finger_joints.empty())
    fit.found.push_back(std::to_string(caps.finger_joints.size()) +
                        " finger joints (VR Controls:Flexor, rotation unit)");
  if (mapping.has_pose()) fit.found.push_back("a pose (X/Y/Z with a length unit, or orientation)");
  if (caps.buttons > 0) fit.found.push_back(std::to_string(caps.buttons) + " buttons");
  std::size_t newtons = 0, unitless = 0;
  for (const ForceChannel& c : caps.force_channels)
    (c.unitless ? unitless : newtons) += 1;
  if (newtons > 0)
    fit.found.push_back(std::to_string(newtons) + " force channels in newtons (PID Magnitude)");
  if (unitless > 0)
    fit.found.push_back(std::to_string(unitless) + " unitless force channels (fraction of 1)");

  char usage_text[24];
  std::snprintf(usage_text, sizeof usage_text, "0x%04X:0x%04X", mapping.application_usage() >> 16,
                mapping.application_usage() & 0xFFFF);
  const std::string application = mapping.application_usage() == 0
                                      ? std::string("no application collection")
                                      : std::string("its application collection is ") + usage_text;
  if (mapping.application_usage() != hid::kUsageGlove) {
    fit.glove_why = application + ", not VR Controls:Glove (0x0003:0x0004)";
  } else if (caps.finger_joints.empty() && !mapping.has_pose() && caps.buttons == 0) {
    fit.glove_why = "no finger joints, pose or buttons it can read";
  } else {
    fit.glove = true;
  }
  const auto app = mapping.application_usage();
  if (app != hid::kUsageHeadTracker && app != hid::kUsageHeadMountedDisplay) {
    fit.tracker_why = application +
                      ", not VR Controls:Head Tracker (0x0003:0x0005) or Head Mounted Display "
                      "(0x0003:0x0006)";
  } else if (!mapping.has_pose()) {
    fit.tracker_why = "no pose it can read (X/Y/Z with a length unit, or an orientation)";
  } else {
    fit.tracker = true;
  }
  return fit;
}

DriverInfo hid_glove_driver_info() {
  DriverInfo info;
  info.name = kHidGloveDriver;
  info.summary =
      "generic HID glove (VR Controls:Glove; flexors, pose, buttons, PID/Haptics forces)";
  info.matches = describes_hid_glove;
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_hid_glove(std::move(transport), clock);
  };
  info.bus = TransportKind::Hid;
  info.device_class = DeviceClass::HapticGlove;
  info.make_twin = [](const DeviceScript& script, const std::string& serial,
                      double haptic_hz) -> std::unique_ptr<SimulatedDevice> {
    return std::make_unique<SimulatedGlove>(script, serial.empty() ? "GLOVE-0001" : serial,
                                            haptic_hz);
  };
  // No list: the channels come from the descriptor; PID magnitudes (newtons) take the fingers in
  // order, a unitless Haptics Intensity stays unused (ChannelLayout's defaults).
  return info;
}

DriverInfo hid_tracker_driver_info() {
  DriverInfo info;
  info.name = kHidTrackerDriver;
  info.summary = "generic HID head tracker (VR Controls:Head Tracker or HMD; pose)";
  info.matches = describes_hid_tracker;
  info.create = [](std::unique_ptr<Transport> transport, Clock& clock) -> std::unique_ptr<Device> {
    return open_hid_tracker(std::move(transport), clock);
  };
  info.bus = TransportKind::Hid;
  info.device_class = DeviceClass::HeadTracker;
  info.make_twin = [](const DeviceScript& script, const std::string& serial,
                      double) -> std::unique_ptr<SimulatedDevice> {
    return std::make_unique<SimulatedHeadTracker>(script, serial.empty() ? "HEAD-0001" : serial);
  };
  return info;
}

}  // namespace bisturi::devices
