// Device interfaces in SI units (metres, radians, newtons, seconds; units in the names). Drivers
// implement them on top of a Transport; the session reads inputs and sends guarded forces.
#pragma once

#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/transport.h"

namespace bisturi::devices {

struct Vec3 {
  double x = 0, y = 0, z = 0;
  bool operator==(const Vec3&) const = default;
};

// Unit quaternion, w first.
struct Quaternion {
  double w = 1, x = 0, y = 0, z = 0;
  bool operator==(const Quaternion&) const = default;
};

// Position in metres and orientation in the device's frame.
struct Pose {
  Vec3 position_m;
  Quaternion orientation;
  bool operator==(const Pose&) const = default;
};

enum class DeviceClass : std::uint8_t { HapticGlove, HapticArm, HeadTracker };
const char* to_string(DeviceClass device_class);

// One force output. Sign convention: every value is the force the device applies to the user's
// hand, in newtons. components == 3: a vector at an end effector (x, y, z in the device's own
// frame, the frame its poses are reported in; pressing on tissue gives a force pointing out of
// the tissue, back towards the hand's approach); components == 1: an actuator along its own
// axis (a finger's), positive resisting the finger's flexion, never pulling it closed.
struct ForceChannel {
  std::string name;  // "end_effector", "thumb", "actuator_2", ...
  std::uint8_t components = 1;
  double max_force_N = 0;             // magnitude limit (vector norm for 3 components)
  double max_force_rate_N_per_s = 0;  // limit on how fast the magnitude of the change may grow
  bool unitless = false;              // the device gave no force unit (Haptics intensity): the
                                      // value is a fraction of max_force_N == 1
  // max_force_N limits each component, not the norm (a device rated "8 N per axis" renders
  // 8 N along every axis at once). A force over it is still scaled down whole, by its largest
  // component, so it keeps its direction.
  bool per_axis = false;
};

// How far a channel's force is from its limit: its norm, or with per_axis its largest component.
double force_extent(const ForceChannel& channel, const double* force_N);

// What the hardware can render, from its datasheet (the driver states it): the force guard and the
// session's haptic coupling read it. 0 means the device does not say.
struct DeviceSpec {
  double max_stiffness_N_per_m = 0.0;  // stiffest virtual spring it renders stably at 1 kHz
  Vec3 workspace_min_m{};              // reachable box in the device frame
  Vec3 workspace_max_m{};
};

// What a device can do, discovered from its descriptor or its info report.
struct Capabilities {
  DeviceClass device_class = DeviceClass::HapticGlove;
  std::size_t end_effectors = 0;             // poses in HapticState::end_effector_poses
  std::size_t buttons = 0;                   // bits in HapticState::buttons
  std::vector<std::string> finger_joints;    // names, in HapticState::finger_joint_angles_rad order
  std::vector<ForceChannel> force_channels;  // in force vector order
  bool head_pose = false;                    // a tracker
  DeviceSpec spec;                           // limits with units

  // Sum of the channels' components: the length of a force vector for send_forces.
  std::size_t force_components() const;
};

struct HapticState {
  Nanoseconds sample_time{0};  // clock time at which the report was read
  std::uint64_t reports = 0;   // input reports handled so far
  std::vector<Pose> end_effector_poses;
  std::uint64_t buttons = 0;  // bit i: button i pressed
  std::vector<double> finger_joint_angles_rad;
  // False while the device does not know where it is (a controller its runtime lost): its poses
  // are the last known ones, and the session holds its forces at zero.
  bool tracked = true;
};

struct TrackerState {
  Nanoseconds sample_time{0};
  std::uint64_t reports = 0;
  Pose head_pose;
};

class Device {
 public:
  virtual ~Device();
  virtual const std::string& driver_name() const = 0;
  virtual const DeviceDescriptor& descriptor() const = 0;
  virtual const Capabilities& capabilities() const = 0;

  // Reads and handles every input report waiting, waiting up to `timeout` for the first. Returns
  // the number handled. Throws DeviceDisconnected when the device is gone (it is then closed),
  // ProtocolError on a malformed report (the state keeps its previous values).
  virtual std::size_t poll(std::chrono::microseconds timeout) = 0;
  // Parses one input report and updates the state, as poll does for each report it reads.
  virtual void handle_report(std::span<const std::uint8_t> report) = 0;

  bool is_open() const { return transport_ != nullptr; }
  // Sends zero forces when it can, then releases the transport. Idempotent, never throws.
  virtual void close();
  // Encodes the driver's "all forces off" reports now, so that send_zero_preempting() needs
  // nothing but the transport. Once, outside the haptic tick (GuardedHaptic's constructor).
  void prepare_preempting_zero();
  // Writes those reports past any write in progress, from any thread, without waiting
  // (Transport::write_preempting). False when they were not prepared, the driver has none or
  // the transport cannot; the caller then zeros through the ordinary path.
  bool send_zero_preempting() noexcept;

 protected:
  explicit Device(std::unique_ptr<Transport> transport, Clock& clock);
  Transport& transport();
  Clock& clock() const { return *clock_; }
  // Reads reports from the transport and calls handle_report for each (the common poll).
  std::size_t poll_transport(std::chrono::microseconds timeout);
  // Hook for close(): the driver's "all forces off" bytes, written before the transport goes.
  virtual void send_zero() {}
  // The reports send_zero() writes, without writing them (none: no preempting zero).
  virtual void zero_reports(std::vector<Bytes>& out) const { out.clear(); }

 private:
  std::unique_ptr<Transport> transport_;
  Clock* clock_;
  Bytes report_;  ///< poll_transport's buffer, reused report after report
  std::vector<Bytes> preempting_zero_;
};

// Gloves and arms. send_forces takes forces that went through the ForceGuard.
class HapticDevice : public Device {
 public:
  virtual const HapticState& state() const = 0;
  // forces_N has capabilities().force_components() values, channel after channel. Throws
  // std::invalid_argument on a wrong length, DeviceDisconnected when the device is gone.
  virtual void send_forces(std::span<const double> forces_N) = 0;

 protected:
  using Device::Device;
  // send_forces' length check: throws std::invalid_argument, naming the device, unless
  // forces_N holds `count` values.
  void expect_force_values(std::span<const double> forces_N, std::size_t count) const;
};

class Tracker : public Device {
 public:
  virtual const TrackerState& state() const = 0;

 protected:
  using Device::Device;
};

// Hot-plug and disconnect events (from DeviceManager in hotplug.h).
enum class DeviceEventKind : std::uint8_t {
  Arrived,       // enumerated for the first time (or again after leaving)
  Opened,        // a driver was opened on it
  Disconnected,  // an open device went away: its forces are stopped
  Reconnected,   // it came back and its driver was opened again
  Removed,       // no longer enumerated
  OpenFailed,    // no driver, or the driver refused it (message says why)
};
const char* to_string(DeviceEventKind kind);

struct DeviceEvent {
  DeviceEventKind kind = DeviceEventKind::Arrived;
  DeviceDescriptor device;
  Nanoseconds time{0};
  std::string message;
};

using DeviceEventHandler = std::function<void(const DeviceEvent&)>;

// The class of device a driver gives, or nullptr.
HapticDevice* as_haptic(Device* device);
Tracker* as_tracker(Device* device);

}  // namespace bisturi::devices
