#pragma once
// A hand for SessionSim tests: an arm's one 3-axis force channel, its first button grasping and
// its second cutting (as the vendor arm's driver lays them out).

#include "bisturi/runtime/session/session_sim.h"

namespace bisturi::runtime::testing {

inline HandSetup arm_hand_setup(double max_force_N) {
  HandSetup h;
  devices::ForceChannel c;
  c.components = 3;
  c.max_force_N = max_force_N;
  h.channels = {c};
  h.channel_roles = {{devices::ChannelUse::Vector, 0}};
  h.button_uses = {devices::ButtonUse::Grasp, devices::ButtonUse::Cut};
  h.max_force_N = max_force_N;
  return h;
}

}  // namespace bisturi::runtime::testing
