// A driver against its twin through the guard and the haptic loop (see device_check.h).

#include "bisturi/runtime/session/device_check.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <stdexcept>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/runtime/session/device_frame.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/session_devices.h"
#include "bisturi/sim/units.h"
#include "haptic_loop.h"
#include "tissue_thread.h"

namespace bisturi::runtime {

namespace {

using devices::Nanoseconds;

/// The default scene with the driver as its haptic device, placed and capped as asked.
SceneDescription check_scene(const DeviceCheckOptions& options) {
  SceneDescription scene = default_scene();
  scene.name = "device check";
  for (DeviceDescription& d : scene.devices) {
    if (d.role != DeviceDescription::Role::Haptic) continue;
    d.driver = options.driver;
    d.simulated = true;
    d.script = "default";
    d.max_force_N = options.max_force_N;
    d.device_to_scene_rotation_deg = options.rotation_deg;
    d.device_to_scene_translation_mm = options.translation_mm;
    d.vendor_id = d.product_id = 0;
    break;
  }
  return scene;
}

DeviceCheckChannel channel_of(const devices::ForceChannel& c, const devices::ChannelRole& role) {
  DeviceCheckChannel out;
  out.role = devices::to_string(role.use);
  if (role.use == devices::ChannelUse::Finger) out.role += " " + std::to_string(role.finger);
  out.components = c.components;
  out.per_axis = c.per_axis;
  out.unitless = c.unitless;
  out.limit_N = c.max_force_N;
  out.rate_limit_N_per_s = c.max_force_rate_N_per_s;
  return out;
}

/// Raises each channel's peaks to the extents of `command` and `output` (components in order).
void track_peaks(const std::vector<devices::ForceChannel>& channels,
                 const std::vector<double>& command, const std::vector<double>& output,
                 std::vector<DeviceCheckChannel>& peaks) {
  std::size_t k = 0;
  for (std::size_t i = 0; i < channels.size(); ++i) {
    const devices::ForceChannel& c = channels[i];
    if (k + c.components > command.size() || k + c.components > output.size()) return;
    peaks[i].peak_command_N =
        std::max(peaks[i].peak_command_N, devices::force_extent(c, command.data() + k));
    peaks[i].peak_output_N =
        std::max(peaks[i].peak_output_N, devices::force_extent(c, output.data() + k));
    k += c.components;
  }
}

}  // namespace

DeviceCheckResult check_device(const DeviceCheckOptions& options,
                               const devices::Registry& registry) {
  const devices::DriverInfo* driver = registry.find_by_name(options.driver);
  if (driver == nullptr) {
    std::string known;
    for (const devices::DriverInfo& d : registry.drivers())
      known += (known.empty() ? "" : ", ") + d.name;
    throw std::invalid_argument("no registered driver is named '" + options.driver +
                                "' (drivers: " + known + ")");
  }
  if (!driver->make_twin)
    throw std::invalid_argument("driver '" + driver->name +
                                "' registers no simulated twin: device check runs a driver "
                                "against its twin");
  if (driver->device_class == devices::DeviceClass::HeadTracker)
    throw std::invalid_argument("driver '" + driver->name +
                                "' opens a head tracker: device check drives haptic devices");

  const SceneDescription scene = check_scene(options);
  std::vector<BuiltSolid> solids = build_solids(scene);
  const auto duration = Nanoseconds{static_cast<std::int64_t>(std::llround(options.seconds * 1e9))};
  const DeviceChoice choice = choose_session_devices(scene);
  const DeviceFrame frame = device_frame_of(*choice.haptic);
  Procedure procedure = make_procedure("default", solids, duration,
                                       devices::SimulatedGlove::kJoints, driver->layout.buttons);
  procedure.first_hand = frame.script_to_device(std::move(procedure.first_hand));

  devices::VirtualClock clock(Nanoseconds{0});
  SessionDevices session_devices(scene, procedure, registry, clock, nullptr);
  devices::HapticDevice& device = session_devices.haptic();
  const devices::Capabilities& caps = device.capabilities();
  HandSetup hand{caps.force_channels,
                 frame,
                 caps.spec,
                 session_devices.haptic_channels(),
                 session_devices.haptic_buttons(),
                 options.max_force_N};
  SessionSim sim(scene, std::move(solids), std::vector<HandSetup>{hand});
  const double haptic_hz = scene.rates.haptic_hz;
  devices::ForceGuard guard(
      sim.guard_channels(),
      devices::force_guard_config_from_json(session_trace_config("", {}, haptic_hz, 0, 0)));
  devices::GuardedHaptic guarded(device, guard, clock);
  devices::HapticState shape;
  shape.end_effector_poses.resize(caps.end_effectors);
  shape.finger_joint_angles_rad.resize(caps.finger_joints.size());
  TissueThread tissue(sim, shape, false, false, {});
  const Nanoseconds period{static_cast<std::int64_t>(std::llround(1e9 / haptic_hz))};
  LiveTickSteps steps(tissue, false, TissueRateController(1, 1, 1e3 / haptic_hz, 0.75));
  HapticLoopParts parts;
  parts.hands = {
      {&guarded, frame,
       devices::buttons_with(session_devices.haptic_buttons(), devices::ButtonUse::Clutch)}};
  parts.steps = &steps;
  parts.sim = &sim;
  parts.clock = &clock;
  parts.head = &session_devices.head();
  parts.step_twins = [&](Nanoseconds t) { session_devices.step_twins(t); };
  HapticLoop loop(std::move(parts), 0, 1);

  DeviceCheckResult r;
  r.driver = driver->name;
  r.summary = driver->summary;
  r.device = devices::describe(device.descriptor());
  r.seconds = options.seconds;
  r.haptic_hz = haptic_hz;
  const std::vector<devices::ForceChannel> limited = sim.guard_channels();
  for (std::size_t i = 0; i < limited.size(); ++i)
    r.channels.push_back(channel_of(limited[i], session_devices.haptic_channels()[i]));
  for (const devices::ButtonUse use : session_devices.haptic_buttons())
    r.buttons.push_back(devices::to_string(use));

  const auto sample_every = Nanoseconds{
      static_cast<std::int64_t>(std::llround(std::max(options.sample_every_s, 1e-3) * 1e9))};
  Nanoseconds next_sample{0};
  while (clock.now() < duration) {
    clock.advance(period);
    (void)loop.tick(clock.now());
    track_peaks(limited, loop.command(), guarded.last_output_N(), r.channels);
    if (clock.now() >= next_sample) {
      const TickOutput* out = loop.step_output();
      r.samples.push_back({static_cast<double>(clock.now().count()) * 1e-9,
                           sim::sim_to_scene(SessionSim::tip_of(loop.state())),
                           out != nullptr && out->contact, loop.command(),
                           guarded.last_output_N()});
      next_sample += sample_every;
    }
  }
  loop.stop();
  session_devices.close();

  const HapticLoopCounters& c = loop.counters();
  r.ticks = c.ticks;
  r.clamped = guard.clamp_count();
  r.rate_limited = guard.rate_limit_count();
  r.guard_latches = c.hands[0].guard_latches;
  r.malformed_reports = c.hands[0].malformed_reports;
  r.silent_ticks = c.hands[0].silent_ticks;
  r.untracked_ticks = c.hands[0].untracked_ticks;
  r.events = sim.events();
  const bool touched = std::any_of(r.events.begin(), r.events.end(), [](const SessionEvent& e) {
    return e.kind == SessionEventKind::Contact;
  });
  if (!touched)
    r.warnings.push_back(
        "the instrument touched nothing: do the driver's poses reach the scene "
        "(units, axes, device_to_scene_*)?");
  if (r.malformed_reports > 0)
    r.warnings.push_back(std::to_string(r.malformed_reports) +
                         " reports were malformed (dropped): the twin and the driver disagree");
  if (r.guard_latches > 0)
    r.warnings.push_back("the force guard latched " + std::to_string(r.guard_latches) +
                         " times: the twin's reports come late or the driver's limits are off");
  return r;
}

}  // namespace bisturi::runtime
