// The "openxr-controller" driver: a headset's hand controller (tracked by the OpenXR runtime on
// the render thread) as a haptic device. The render thread pushes each frame's controller state
// into a ControllerFeed as a fixed input report; the driver reads those reports on the haptic
// thread like any device's bytes (so a recording holds them and replay plays them back through
// the same driver), and writes its force channel back as a vibration report the render thread
// takes and applies (xrApplyHapticFeedback).
//
// Input report, 44 bytes, little-endian:
//   0      u8   type, 0x01
//   1      u8   flags: bit 0 active (tracked this frame); other bits zero
//   2..3   u16  zero
//   4..11  i64  t_ns: when the runtime sampled the pose (its clock)
//   12..23 f32  grip position x, y, z in metres (the world of the OpenXR sink)
//   24..39 f32  grip orientation x, y, z, w (unit quaternion, within 1e-3)
//   40..43 f32  trigger, 0 released .. 1 pulled
// Output report, 8 bytes: 0 u8 type 0x02, 1 u8 sequence, 2..3 zero, 4..7 f32 amplitude 0..1.
//
// Capabilities: one end effector (the grip), button 0 while trigger > 0.5, one 1-component force
// channel "vibration" (role Finger 0: the session sends it the instrument's contact force and
// its grasp hold). send_forces writes amplitude = clamp(|F| / kMaxForceN, 0, 1): the force guard
// runs before it as for any device, so its limits, NaN checks, watchdog and latches give 0.
#pragma once

#include <cstdint>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/devices/device.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/virtual_transport.h"

namespace bisturi::devices {

inline constexpr const char* kOpenXrControllerDriver = "openxr-controller";

namespace controller_protocol {
inline constexpr std::uint8_t kState = 0x01;
inline constexpr std::uint8_t kVibration = 0x02;
inline constexpr std::size_t kInputSize = 44;
inline constexpr std::size_t kOutputSize = 8;
inline constexpr std::uint8_t kActive = 0x01;
inline constexpr double kMaxForceN = 4.0;  // the force that vibrates at full amplitude
inline constexpr double kMaxForceRateNPerS = 400.0;
inline constexpr double kTriggerPressed = 0.5;
}  // namespace controller_protocol

struct ControllerSample {
  std::int64_t t_ns = 0;
  bool active = false;
  Vec3 position_m;
  Quaternion orientation;  // w first, as Pose
  double trigger = 0.0;
};

Bytes encode_controller_report(const ControllerSample& sample);
// Amplitude of a vibration output report; nullopt when it is not one (size, type, range).
std::optional<double> decode_vibration_report(std::span<const std::uint8_t> report);

// The render thread's end of the controller's link. Thread-safe. open() makes the transport the
// driver is opened on (once); push() and take_vibration() are no-ops until then.
class ControllerFeed {
 public:
  // The transport for the driver (its descriptor names the driver), or nullptr when it has been
  // opened already.
  std::unique_ptr<Transport> open();
  // open() when `driver` is this feed's (openxr-controller), else nullptr: the session's hook
  // for drivers fed from inside the process.
  std::unique_ptr<Transport> open_for(const DriverInfo& driver);
  [[nodiscard]] bool opened() const;
  void push(const ControllerSample& sample);
  // The newest vibration amplitude written since the last call (older ones are superseded).
  std::optional<double> take_vibration();
  // Reports the driver wrote that were not vibration reports.
  [[nodiscard]] std::uint64_t rejected() const;

 private:
  mutable std::mutex mutex_;
  std::unique_ptr<VirtualTransport> device_side_;
  std::uint64_t rejected_ = 0;
};

std::unique_ptr<HapticDevice> open_openxr_controller(std::unique_ptr<Transport> transport,
                                                     Clock& clock);
DriverInfo openxr_controller_driver_info();

}  // namespace bisturi::devices
