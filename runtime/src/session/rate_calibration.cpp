// The first tissue rate of an adaptive session (see rate_calibration.h).

#include "rate_calibration.h"

#include <algorithm>
#include <chrono>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_export.h"
#include "step_schedule.h"

namespace bisturi::runtime {

RateCalibration calibrate_tissue_rate(const SceneDescription& scene,
                                      const std::vector<BuiltSolid>& solids,
                                      const SessionSimOptions& sim_options, double max_load,
                                      std::uint32_t max_ticks) {
  // A Dlfl does not copy: the copy is rebuilt from the solids' polygons.
  std::vector<BuiltSolid> copies;
  copies.reserve(solids.size());
  for (const BuiltSolid& s : solids)
    copies.push_back(
        {s.description, build_oriented_manifold(export_polygons(s.mesh).polygons), 0.0});
  SessionSim sim(scene, std::move(copies), std::vector<devices::ForceChannel>{}, sim_options);
  // No end effector: the probe sits at the origin, away from the scene's solids (or touching
  // one, which costs what contact costs). The first steps settle under gravity: every vertex
  // is awake, as under the probe.
  const devices::HapticState rest;
  // Multirate: two whole periods, since a step's cost depends on where it is in its period (the
  // far job runs early in it) and the first period has no estimate of the job yet.
  const int interval = std::max(scene.simulation.far_field_interval, 1);
  const int steps = interval > 1 ? 2 * std::min(interval, 64) + 1 : 9;
  std::vector<double> ms;
  for (int k = 0; k < steps; ++k) {
    const auto start = std::chrono::steady_clock::now();
    sim.tick(rest, 1);
    ms.push_back(std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
                     .count());
  }
  std::nth_element(ms.begin(), ms.begin() + steps / 2, ms.end());
  RateCalibration out;
  out.median_step_ms = ms[steps / 2];
  out.ticks_per_step =
      ticks_per_step_for(out.median_step_ms, sim.haptic_period_ms(), max_load, max_ticks);
  return out;
}

}  // namespace bisturi::runtime
