#pragma once
// The liver scene (config/liver.toml) and its scripted procedure, stepped as a live session's
// tissue thread steps it on a 2-core machine: at 500 Hz (two haptic ticks a step), in virtual
// time, the first hand's device state from the script.

#include <cstdint>
#include <string>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"

namespace bisturi::runtime {

/// Force channels of a glove of five fingers of 3 N.
inline std::vector<devices::ForceChannel> glove_channels() {
  std::vector<devices::ForceChannel> channels(5);
  for (devices::ForceChannel& c : channels)
    c.max_force_N = 3.0;
  return channels;
}

struct LiverProcedure {
  SceneDescription scene = read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/liver.toml");
  Procedure procedure =
      make_procedure("default", build_solids(scene),
                     devices::Nanoseconds(static_cast<std::int64_t>(scene.duration_s * 1e9)),
                     devices::SimulatedGlove::kJoints);
  SessionSim sim{scene, build_solids(scene), glove_channels()};

  /// Steps in the scene's duration.
  [[nodiscard]] std::int64_t steps() const {
    return static_cast<std::int64_t>(scene.duration_s * 500.0);
  }
  /// Step k (from 1), at k x 2 ms.
  const TickOutput& step(std::int64_t k) {
    const devices::Nanoseconds t(k * 2'000'000);
    devices::HapticState state;
    state.sample_time = t;
    state.end_effector_poses = {procedure.first_hand.pose_at(t)};
    state.finger_joint_angles_rad =
        procedure.first_hand.joints_at(t, devices::SimulatedGlove::kJoints);
    state.buttons = procedure.first_hand.buttons_at(t);
    return sim.tick(state, 2);
  }
};

}  // namespace bisturi::runtime
