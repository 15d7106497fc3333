#pragma once
// The scripted procedure that drives the simulated haptic devices and head tracker of a scene whose
// devices use script = "default": approach the organ, palpate it, grasp a vessel's wall and pull
// it, release, then cut along a path. The timeline is laid out over the session's duration (so a
// one-second run goes through every phase). The targets are the scene's [procedure] table
// (ProcedureDescription: points on the organ and on the vessel, the cut's path, with outward
// normals the instrument comes in along); a scene without one gets the top of the first solid,
// the anterior (-y) wall of the second and a 24 mm cut across the first's top, from the built
// solids' bounds. During the cut the hand's pose turns so that the scalpel's blade (the pose's
// +z) points out along the cut's normal. The head looks at the solids from in front and above.
// Device poses are SI metres in the scene's world frame.

#include <chrono>
#include <string>
#include <vector>

#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/scene_builder.h"

namespace bisturi::runtime {

struct ProcedurePhase {
  std::string name;  ///< "approach", "palpate", "grasp", "cut", ...
  devices::Nanoseconds begin{0};
  devices::Nanoseconds end{0};
};

struct Procedure {
  devices::DeviceScript first_hand;  ///< the first haptic device's script
  /// The other hands' scripts, in order (a hand past them follows the first's).
  std::vector<devices::DeviceScript> other_hands;
  devices::DeviceScript head;
  std::vector<ProcedurePhase> phases;
};

/// The procedure over `duration` for `solids` (at least one), the first hand following `script`.
/// `buttons`: what the device's buttons do (its driver's ChannelLayout::buttons; empty: button 0
/// cuts): the script presses the cut button for the incision and holds a grasp button, where
/// there is one, while the hand closes. Throws SceneFileError for an unknown script name.
Procedure make_procedure(const std::string& script, const std::vector<BuiltSolid>& solids,
                         devices::Nanoseconds duration, std::size_t hand_joints,
                         const std::vector<devices::ButtonUse>& buttons = {});

/// One hand's script over the same timeline:
///  - "default": approach, palpate, grasp the vessel and pull it, release, cut;
///  - "hold": the assisting hand: comes down beside the middle of the cut's path (10 mm to its
///    side on the first solid's surface), grasps the tissue there before the incision, lifts it
///    4 mm and draws it 2 mm away from the path, holds it so through the cut, then lets go.
/// Throws SceneFileError for another name.
devices::DeviceScript make_hand_script(const std::string& script,
                                       const std::vector<BuiltSolid>& solids,
                                       devices::Nanoseconds duration, std::size_t joints,
                                       const std::vector<devices::ButtonUse>& buttons = {});

}  // namespace bisturi::runtime
