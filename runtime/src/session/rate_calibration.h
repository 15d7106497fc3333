#pragma once
// Where the adaptive tissue rate starts. The rate controller (step_schedule.h) only halves the
// rate after 48 steps at each level, so a session whose organ steps far slower than the haptic
// period spent its first few hundred ticks late (a 6.5k-vertex organ on the 2-core Zen 1 machine:
// about 550 late ticks in 4 s, going 1000 -> 500 -> 250 -> 125 Hz). Instead, a throwaway copy of
// the solids steps a few times before the session starts, and the median step picks the first
// rate; the controller adapts from there.

#include <cstdint>
#include <vector>

#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"

namespace bisturi::runtime {

struct RateCalibration {
  double median_step_ms = 0.0;
  std::uint32_t ticks_per_step = 1;
};

/// Steps a copy of `solids` (the probe away from the tissue, no instrument closed) a few times
/// and picks the ticks per step as TissueRateController would (ticks_per_step_for). The solids
/// themselves are not touched.
RateCalibration calibrate_tissue_rate(const SceneDescription& scene,
                                      const std::vector<BuiltSolid>& solids,
                                      const SessionSimOptions& sim_options, double max_load,
                                      std::uint32_t max_ticks);

}  // namespace bisturi::runtime
