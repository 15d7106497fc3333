#pragma once
// The force command's slew: no channel's command changes faster than the device says it can
// render (ForceChannel::max_force_rate_N_per_s), whatever the simulation asks for. A contact
// that flickers on and off from one tissue step to the next, a grasp that closes, a finger that
// touches: each reaches the hand as a ramp, never as a kick, and a flicker at the tick rate
// stays below rate x period in amplitude. The force guard keeps its own rate limit as the
// safety net behind this; zeros for faults bypass both (they latch the guard).
//
// A 3-component channel keeps the computed direction: only its magnitude is slewed, and a
// computed zero is sent as zero at once (no force continues in a direction nobody computed).

#include <span>
#include <vector>

#include "bisturi/devices/device.h"

namespace bisturi::runtime {

class CommandSlew {
 public:
  /// `channels`: the device's, in command order; `period_s`: the haptic tick.
  CommandSlew(const std::vector<devices::ForceChannel>& channels, double period_s);

  /// Limits `command` (force components, channel after channel) against the last command
  /// that left here. Returns true when some channel was held back. Never allocates.
  bool apply(std::span<double> command) noexcept;
  /// The output went to zero another way (a held display, a fault): ramps start from zero.
  void reset() noexcept;

 private:
  struct Channel {
    std::size_t offset = 0;
    std::size_t components = 1;
    double step_N = 0.0;  ///< the most a command may change in one tick
  };
  std::vector<Channel> channels_;
  std::vector<double> last_;
};

}  // namespace bisturi::runtime
