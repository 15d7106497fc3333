#pragma once
// The haptic loop's test rig (tests/session_haptic_loop_test.cpp,
// tests/session_tick_allocations_test.cpp): an arm and a head tracker on virtual transports with
// their twins, the force guard, the session's simulation, and the loop, on a virtual clock.

#include <atomic>
#include <chrono>
#include <functional>
#include <memory>
#include <string>

#include <glm/vec3.hpp>

#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/virtual_transport.h"
#include "bisturi/runtime/session/device_frame.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/session_sim.h"
#include "session/haptic_loop.h"
#include "session/step_schedule.h"
#include "session/tissue_thread.h"

namespace bisturi::runtime::testing {

using devices::Nanoseconds;
using std::chrono::milliseconds;

// The test scene's organ: a sphere of radius 28 mm about (32.25, 32.25, 32.25) mm.
inline const glm::dvec3 kOrganTop_mm{32.25, 32.25, 60.25};

/// The organ alone, with the arm (device frame turned `rotation_deg` in the scene) and a head
/// tracker.
inline SceneDescription arm_scene(const std::string& rotation) {
  return parse_scene(R"(
[[solids]]
name = "organ"
phantom = "sphere"
dims = [44, 44, 44]
spacing_mm = 1.5
a_mm = 28.0
decimate = 0.12
smooth = 5

[solids.material]
stiffness_N_per_m = 400.0
damping_N_s_per_m = 0.8

[[solids.anchors]]
point_mm = [32.25, 32.25, 12.0]
normal = [0.0, 0.0, 1.0]
distance_mm = 0.0

[[devices]]
name = "arm"
driver = "vendor-arm"
role = "haptic"
max_force_N = 2.0
device_to_scene_rotation_deg = )" +
                         rotation + R"(

[[devices]]
name = "head"
driver = "hid-tracker"
role = "head-tracker"
)",
                     "arm_scene.toml");
}

inline devices::Pose at_mm(const glm::dvec3& p_mm) {
  devices::Pose pose;
  pose.position_m = {p_mm.x * 1e-3, p_mm.y * 1e-3, p_mm.z * 1e-3};
  return pose;
}

/// The tissue's steps, which a test can hang: then no step is taken and every tick gets the
/// last finished one, late (a tissue thread stuck in a step).
class HangableSteps final : public TickSteps {
 public:
  explicit HangableSteps(TickSteps& inner) : inner_(inner) {}
  TissueThread::Push push(std::span<const devices::HapticState> states, std::uint32_t ticks,
                          bool blood_held) override {
    return hung ? TissueThread::Push::Behind : inner_.push(states, ticks, blood_held);
  }
  TissueThread::TickStep step_for(std::uint64_t k, std::uint64_t due) override {
    if (hung) {
      TissueThread::TickStep old = last_;
      old.late = true;
      return old;
    }
    last_ = inner_.step_for(k, due);
    return last_;
  }
  bool blood_held(std::uint64_t k, bool now) override { return inner_.blood_held(k, now); }
  std::uint32_t ticks_per_step(std::uint64_t k, std::uint32_t n) override {
    return inner_.ticks_per_step(k, n);
  }
  [[nodiscard]] std::uint64_t backlog() const override { return inner_.backlog(); }
  bool hung = false;

 private:
  TickSteps& inner_;
  TissueThread::TickStep last_;
};

/// A session's haptic side on a virtual clock: the scene's devices (twins), the guard, the
/// tissue stepped inside the tick (or, `threaded`, on its own thread as in a live session), and
/// the loop.
struct Rig {
  Rig(const SceneDescription& scene_in, Procedure procedure, bool threaded = false)
      : scene(scene_in), clock(Nanoseconds{0}), registry(devices::builtin_registry()) {
    // The twins behind virtual transports, the real drivers on the host side (as SessionDevices
    // opens simulated devices).
    arm_twin = std::make_unique<devices::SimulatedArm>(procedure.first_hand, "ARM-0001", 1000.0);
    head_twin = std::make_unique<devices::SimulatedHeadTracker>(procedure.head);
    devices::VirtualPair arm_pair = devices::make_virtual_pair(arm_twin->descriptor());
    arm_twin->attach(std::move(arm_pair.device));
    arm_device = registry.open(std::move(arm_pair.host), clock);
    devices::VirtualPair head_pair = devices::make_virtual_pair(head_twin->descriptor());
    head_twin->attach(std::move(head_pair.device));
    head_device = registry.open(std::move(head_pair.host), clock);
    arm = devices::as_haptic(arm_device.get());
    guard = std::make_unique<devices::ForceGuard>(arm->capabilities().force_channels,
                                                  devices::ForceGuardConfig{});
    guarded = std::make_unique<devices::GuardedHaptic>(*arm, *guard, clock);
    SessionSimOptions options;
    options.device_frame = device_frame_of(scene.devices.at(0));
    options.device_spec = arm->capabilities().spec;
    sim = std::make_unique<SessionSim>(scene, build_solids(scene),
                                       arm->capabilities().force_channels, options);
    devices::HapticState shape;
    shape.end_effector_poses.resize(arm->capabilities().end_effectors);
    shape.finger_joint_angles_rad.resize(arm->capabilities().finger_joints.size());
    tissue = std::make_unique<TissueThread>(
        *sim, shape, threaded, false,
        [](const TickOutput&, std::span<const devices::HapticState>, double) {});
    steps = std::make_unique<LiveTickSteps>(*tissue, false, TissueRateController(1, 1, 1.0));
    hangable = std::make_unique<HangableSteps>(*steps);
    HapticLoopParts parts;
    parts.hands = {{guarded.get(), options.device_frame, 0}};
    parts.steps = hangable.get();
    parts.sim = sim.get();
    parts.clock = &clock;
    parts.head = devices::as_tracker(head_device.get());
    parts.display_live = &display_live;
    parts.display_deadline_ns = &display_deadline_ns;
    parts.step_twins = [this](Nanoseconds t) {
      if (twins_running) twins_running(true);
      if (!arm_muted) arm_twin->step(t);
      head_twin->step(t);
      if (twins_running) twins_running(false);
    };
    // Threaded, the tissue gets the live session's lag (3 ticks) to finish a step.
    loop = std::make_unique<HapticLoop>(std::move(parts), threaded ? 3 : 0, 1);
  }
  /// Ticks every millisecond until `until`.
  void run_to(Nanoseconds until) {
    while (clock.now() < until) {
      clock.advance(milliseconds(1));
      (void)loop->tick(clock.now());
    }
  }
  /// The force the arm's motors apply now, in its own frame.
  [[nodiscard]] glm::dvec3 applied() const {
    const devices::Vec3 f = arm_twin->applied_force_N();
    return {f.x, f.y, f.z};
  }

  SceneDescription scene;
  devices::VirtualClock clock;
  devices::Registry registry;
  std::unique_ptr<devices::SimulatedArm> arm_twin;
  std::unique_ptr<devices::SimulatedHeadTracker> head_twin;
  std::unique_ptr<devices::Device> arm_device, head_device;
  devices::HapticDevice* arm = nullptr;
  std::unique_ptr<devices::ForceGuard> guard;
  std::unique_ptr<devices::GuardedHaptic> guarded;
  std::unique_ptr<SessionSim> sim;
  std::unique_ptr<TissueThread> tissue;
  std::unique_ptr<LiveTickSteps> steps;
  std::unique_ptr<HangableSteps> hangable;
  std::unique_ptr<HapticLoop> loop;
  bool arm_muted = false;  ///< the arm's twin sends nothing
  std::atomic<bool> display_live{true};
  std::atomic<std::int64_t> display_deadline_ns{-1};  ///< the renderer's; -1: not watched
  /// Called with true before the twins step inside a tick and false after (a test that looks at
  /// the tick alone sets it: the twins stand in for the hardware).
  std::function<void(bool)> twins_running;
};

/// The arm comes down onto the organ's top (scene normal +z) and presses 2 mm in, its poses
/// given in its own frame (the inverse of the scene's rotation).
inline Procedure pressing_arm(const DeviceFrame& frame) {
  Procedure p;
  const auto device_point = [&](const glm::dvec3& scene_mm) {
    // p_scene = R p_device (no translation in these scenes): p_device = R^T p_scene, through
    // the frame's own force rotation (the same R^T).
    return frame.force_to_device(scene_mm);
  };
  p.first_hand.motion.push_back(
      {Nanoseconds{0}, at_mm(device_point(kOrganTop_mm + glm::dvec3(0, 0, 12))), {}});
  p.first_hand.motion.push_back(
      {milliseconds(300), at_mm(device_point(kOrganTop_mm + glm::dvec3(0, 0, 4))), {}});
  p.first_hand.motion.push_back(
      {milliseconds(700), at_mm(device_point(kOrganTop_mm - glm::dvec3(0, 0, 5))), {}});
  p.head.motion.push_back({Nanoseconds{0}, devices::Pose{}, {}});
  return p;
}

}  // namespace bisturi::runtime::testing
