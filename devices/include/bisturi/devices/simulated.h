// Simulated twins: devices that speak exactly the byte protocols of the real ones through the
// device side of a virtual transport, driven by scripts (motions, button presses, contacts). For
// tests, the demo and benchmarks; the drivers on the host side cannot tell them from hardware.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <span>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/virtual_transport.h"

namespace bisturi::devices {

// Pose (and finger joints) at a time; linear in between (normalised lerp for orientations),
// held before the first and after the last key.
struct MotionKey {
  Nanoseconds t{0};
  Pose pose;
  std::vector<double> joints_rad;
};

struct ButtonPress {
  Nanoseconds t{0};
  std::uint32_t button = 0;
  bool down = true;
};

// Between begin and end, joint `joint` cannot close beyond max_angle_rad (the finger touches an
// object); the twin reports the clamped angle.
struct Contact {
  Nanoseconds begin{0}, end{0};
  std::size_t joint = 0;
  double max_angle_rad = 0;
};

struct DeviceScript {
  std::vector<MotionKey> motion;  // sorted by t
  std::vector<ButtonPress> presses;
  std::vector<Contact> contacts;

  Pose pose_at(Nanoseconds t) const;
  std::vector<double> joints_at(Nanoseconds t, std::size_t joints) const;
  std::uint64_t buttons_at(Nanoseconds t) const;
};

class SimulatedDevice {
 public:
  virtual ~SimulatedDevice();
  const DeviceDescriptor& descriptor() const { return descriptor_; }

  // Takes the device side of a link (replacing any previous one); output reports from the host
  // are handled as they are written.
  void attach(std::unique_ptr<VirtualTransport> device_side);
  // For VirtualBus::plug. The twin must outlive the bus entry.
  VirtualBus::Connector connector();
  // Simulates an unplug of the current link (both sides see DeviceDisconnected).
  void disconnect();
  // Simulates a device that holds off its endpoint: the host's next write blocks for `duration`.
  void stall_host_writes(Nanoseconds duration);
  bool attached() const;

  // Sends the input report due at time t, at most one per call and one per period. Returns
  // whether one was sent (false when detached or not due).
  bool step(Nanoseconds t);
  // Output reports received from the host so far.
  std::uint64_t outputs_received() const;

 protected:
  SimulatedDevice(DeviceDescriptor descriptor, Nanoseconds period);
  // Called with the twin's mutex held.
  virtual Bytes input_report(Nanoseconds t) = 0;
  virtual void on_output(std::span<const std::uint8_t> report) = 0;
  // Writes a report to the host now (from on_output: answers). Mutex held.
  void send_locked(std::span<const std::uint8_t> report);
  mutable std::mutex mutex_;

 private:
  void drain();
  DeviceDescriptor descriptor_;
  Nanoseconds period_;
  bool have_sent_ = false;
  Nanoseconds next_{0};
  std::uint64_t outputs_ = 0;
  std::unique_ptr<VirtualTransport> link_;
  Bytes output_;  ///< drain()'s buffer, reused (its slot in the link keeps the one before)
};

// A force-feedback glove: VR Controls:Glove, hand pose, 15 finger joints (12-bit flexors in
// degrees), 4 buttons, 5 PID constant-force actuators (0-5 N) and one Haptics intensity channel.
class SimulatedGlove final : public SimulatedDevice {
 public:
  static constexpr std::size_t kJoints = 15;
  static constexpr std::size_t kActuators = 5;
  explicit SimulatedGlove(DeviceScript script, std::string serial = "GLOVE-0001",
                          double rate_hz = 1000.0);
  static Bytes report_descriptor();
  // The last actuator forces the host sent (newtons) and vibration intensity (0-1).
  std::vector<double> actuator_forces_N() const;
  double vibration() const;

 private:
  Bytes input_report(Nanoseconds t) override;
  void on_output(std::span<const std::uint8_t> report) override;
  DeviceScript script_;
  std::vector<double> forces_N_;
  double vibration_ = 0;
};

// A head tracker: VR Controls:Head Tracker, no report ids, position in 0.1 mm (int32) and an
// orientation quaternion.
class SimulatedHeadTracker final : public SimulatedDevice {
 public:
  explicit SimulatedHeadTracker(DeviceScript script, std::string serial = "HEAD-0001",
                                double rate_hz = 500.0);
  static Bytes report_descriptor();

 private:
  Bytes input_report(Nanoseconds t) override;
  void on_output(std::span<const std::uint8_t>) override {}
  DeviceScript script_;
};

// The vendor haptic arm (docs/devices/vendor-haptic-protocol.md), with its device-side watchdog
// (forces off after 100 ms without a force packet). Its info packet states the datasheet figures
// below (the protocol document's example arm).
class SimulatedArm final : public SimulatedDevice {
 public:
  static constexpr double kMaxStiffness_N_per_m = 2000.0;
  static constexpr double kWorkspaceMin_m[3] = {-0.080, -0.060, -0.050};
  static constexpr double kWorkspaceMax_m[3] = {0.080, 0.060, 0.070};

  explicit SimulatedArm(DeviceScript script, std::string serial = "ARM-0001",
                        double rate_hz = 1000.0, double max_force_N = 8.0,
                        double max_force_rate_N_per_s = 400.0);
  // The force the motors apply now (zero after the device watchdog tripped).
  Vec3 applied_force_N() const;
  std::uint64_t force_packets() const;
  std::uint64_t bad_packets() const;

 private:
  Bytes input_report(Nanoseconds t) override;
  void on_output(std::span<const std::uint8_t> report) override;
  DeviceScript script_;
  double max_force_N_, max_rate_;
  Vec3 force_N_;
  Nanoseconds last_force_time_{0};
  Nanoseconds now_{0};
  bool watchdog_tripped_ = false;
  std::uint64_t force_packets_ = 0, bad_packets_ = 0;
  std::uint8_t sequence_ = 0;
};

}  // namespace bisturi::devices
