#pragma once
// The scripted procedure that drives the simulated glove and head tracker of a scene whose
// devices use script = "default": approach the first solid, palpate it, grasp the second solid's
// wall and pull it, release, then cut across the top of the first solid. The timeline is laid out
// over the session's duration (so a one-second run goes through every phase) and the targets
// come from the built solids' bounds. Device poses are SI metres in the scene's world frame.

#include <chrono>
#include <string>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/scene_builder.h"

namespace bisturi::runtime {

struct ProcedurePhase {
  std::string name;  ///< "approach", "palpate", "grasp", "cut", ...
  devices::Nanoseconds begin{0};
  devices::Nanoseconds end{0};
};

struct Procedure {
  devices::DeviceScript glove;
  devices::DeviceScript head;
  std::vector<ProcedurePhase> phases;
};

/// The default procedure over `duration` for `solids` (at least one). Throws SceneFileError for
/// a script name other than "default".
Procedure make_procedure(const std::string& script, const std::vector<BuiltSolid>& solids,
                         devices::Nanoseconds duration, std::size_t glove_joints);

}  // namespace bisturi::runtime
