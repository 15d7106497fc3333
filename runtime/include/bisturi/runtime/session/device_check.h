#pragma once
// A driver checked against its twin the way a session would use it, without a headset: the
// default scene's organ, the driver's twin following the default procedure (approach, palpate,
// grasp, cut, pressing the buttons its layout gives roles), the real driver on the host side,
// the force guard and the haptic loop, ticked in virtual time with the tissue inside the tick.
// What comes out is what an integrator wants to see on day one: the poses in the scene's frame,
// the commands and what the guard let through per channel against its limits, clamps, rate
// limiting, latches, malformed reports and the events the instrument caused.

#include <array>
#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/devices/registry.h"
#include "bisturi/runtime/session/session_sim.h"

namespace bisturi::runtime {

struct DeviceCheckOptions {
  std::string driver;        ///< a registered driver with a twin
  double seconds = 4.0;      ///< the procedure's length (virtual time)
  double max_force_N = 3.0;  ///< the scene's cap on the device's force
  double sample_every_s = 0.25;
  /// Where the device sits in the scene (device_to_scene_*: the twin follows the inverse).
  std::array<double, 3> rotation_deg{0.0, 0.0, 0.0};
  std::array<double, 3> translation_mm{0.0, 0.0, 0.0};
};

/// One force channel's figures: its limits (the lower of the device's and the scene's) and the
/// largest command (before the guard) and output (after it), each as the limit measures it (the
/// norm, or the largest component for a per-axis channel).
struct DeviceCheckChannel {
  std::string role;  ///< "vector", "finger 2", "unused"
  std::uint32_t components = 1;
  bool per_axis = false;
  bool unitless = false;
  double limit_N = 0.0;
  double rate_limit_N_per_s = 0.0;
  double peak_command_N = 0.0;
  double peak_output_N = 0.0;
};

/// The state at a sample time: the instrument's tip in the scene, the command and the output.
struct DeviceCheckSample {
  double time_s = 0.0;
  glm::dvec3 tip_mm{0.0};
  bool contact = false;
  std::vector<double> command_N;
  std::vector<double> output_N;
};

struct DeviceCheckResult {
  std::string driver;
  std::string summary;  ///< the driver's one line
  std::string device;   ///< the twin's descriptor as the host saw it
  double seconds = 0.0;
  double haptic_hz = 0.0;
  std::vector<DeviceCheckChannel> channels;
  std::vector<std::string> buttons;  ///< what each button does, by bit
  std::uint64_t ticks = 0;
  std::uint64_t clamped = 0;       ///< commands the guard scaled down to a limit
  std::uint64_t rate_limited = 0;  ///< commands the guard slowed to the rate limit
  std::uint64_t guard_latches = 0;
  std::uint64_t malformed_reports = 0;
  std::uint64_t silent_ticks = 0;
  std::uint64_t untracked_ticks = 0;
  std::vector<SessionEvent> events;
  std::vector<DeviceCheckSample> samples;
  std::vector<std::string> warnings;
};

/// Runs the check. Throws std::invalid_argument for an unknown driver, one without a twin or
/// one that is not a haptic device, and what opening the driver throws.
DeviceCheckResult check_device(const DeviceCheckOptions& options,
                               const devices::Registry& registry);

}  // namespace bisturi::runtime
