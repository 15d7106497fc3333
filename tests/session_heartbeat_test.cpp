// The heartbeat (sim/pulse.h) through the session's simulation: the default scene's vessel with a
// lumen pressure of 80/120 mmHg at 72 beats a minute pulses at that period, by an amount a wall
// of its stiffness gives, and a probe resting on it feels the beat.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <vector>

#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/sim/pulse.h"
#include "bisturi/sim/units.h"

namespace bisturi::runtime {
namespace {

constexpr double kBeatsPerMinute = 72.0;
constexpr std::size_t kVessel = 1;

TEST(Heartbeat, TheWaveformRisesToSystoleAndClosesItsCycle) {
  EXPECT_DOUBLE_EQ(sim::cardiac_waveform(0.0), 0.0);
  EXPECT_NEAR(sim::cardiac_waveform(0.15), 1.0, 1e-12);
  EXPECT_NEAR(sim::cardiac_waveform(1.0 - 1e-12), 0.0, 1e-9) << "continuous into the next beat";
  EXPECT_NEAR(sim::cardiac_waveform(2.4), sim::cardiac_waveform(0.4), 1e-12);
  for (int i = 0; i < 1000; ++i) {
    const double w = sim::cardiac_waveform(i / 1000.0);
    EXPECT_GE(w, 0.0);
    EXPECT_LE(w, 1.0);
  }
}

/// The default scene, its vessel's wall `stiffer` times as stiff, pulsing from 80 mmHg to
/// 80 + pulse_mmHg (none at 0).
SceneDescription pulsing_scene(double pulse_mmHg, double stiffer = 1.0) {
  SceneDescription scene = default_scene();
  scene.physiology.heart_rate_bpm = kBeatsPerMinute;
  if (pulse_mmHg > 0.0)
    scene.solids.at(kVessel).pulse_mmHg = std::array<double, 2>{80.0, 80.0 + pulse_mmHg};
  scene.solids.at(kVessel).material.stiffness_N_per_m *= stiffer;
  return scene;
}

devices::HapticState tip_at_mm(const glm::dvec3& p_mm) {
  devices::HapticState s;
  const glm::dvec3 m = sim::scene_to_sim(p_mm);
  s.end_effector_poses.resize(1);
  s.end_effector_poses[0].position_m = {m.x, m.y, m.z};
  return s;
}

/// The vessel's mean distance (mm) of its free vertices from its axis (vertical, through the
/// rest centroid), every tick for `seconds`.
std::vector<double> vessel_radius_mm(double pulse_mmHg, double seconds, double stiffer = 1.0) {
  const SceneDescription scene = pulsing_scene(pulse_mmHg, stiffer);
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  const sim::SoftBody& vessel = sim.world().body(kVessel);
  glm::dvec2 axis(0.0);
  std::size_t n = 0;
  for (std::size_t i = 0; i < vessel.positions().size(); ++i) {
    if (vessel.masses()[i] <= 0.0) continue;
    axis += glm::dvec2(vessel.positions()[i]);
    ++n;
  }
  axis /= static_cast<double>(n);
  const devices::HapticState away = tip_at_mm({0.0, 0.0, 500.0});
  std::vector<double> radius;
  const auto ticks = static_cast<int>(seconds * scene.rates.haptic_hz);
  for (int k = 0; k < ticks; ++k) {
    (void)sim.tick(away);
    double sum = 0.0;
    std::size_t m = 0;
    for (std::size_t i = 0; i < vessel.positions().size(); ++i) {
      if (vessel.masses()[i] <= 0.0 || vessel.anchored(VertexId(static_cast<std::uint32_t>(i))))
        continue;
      sum += glm::length(glm::dvec2(vessel.positions()[i]) - axis);
      ++m;
    }
    radius.push_back(sum / static_cast<double>(m) * 1e3);
  }
  return radius;
}

/// The widest point of each whole beat after the first (the wall settles in the first), and each
/// beat's swing (widest less narrowest).
struct Beats {
  std::vector<std::size_t> peaks;
  std::vector<double> swing_mm;
};
Beats beats_of(const std::vector<double>& r) {
  const auto beat = static_cast<std::size_t>(std::lround(60.0 / kBeatsPerMinute * 1000.0));
  Beats b;
  for (std::size_t start = beat; start + beat <= r.size(); start += beat) {
    const auto first = r.begin() + static_cast<std::ptrdiff_t>(start);
    const auto last = first + static_cast<std::ptrdiff_t>(beat);
    b.peaks.push_back(static_cast<std::size_t>(std::max_element(first, last) - r.begin()));
    b.swing_mm.push_back(*std::max_element(first, last) - *std::min_element(first, last));
  }
  return b;
}

TEST(Heartbeat, TheVesselPulsesAtTheHeartRate) {
  const Beats b = beats_of(vessel_radius_mm(40.0, 3.6));
  const double period_s = 60.0 / kBeatsPerMinute;
  ASSERT_GE(b.peaks.size(), 3u);
  for (std::size_t i = 1; i < b.peaks.size(); ++i) {
    const double measured_s = static_cast<double>(b.peaks[i] - b.peaks[i - 1]) * 1e-3;
    EXPECT_NEAR(measured_s, period_s, 0.02 * period_s) << "beat " << i;
  }
  const double swing = b.swing_mm.back();
  RecordProperty("swing_mm", std::to_string(swing));
  for (const double s : b.swing_mm)
    EXPECT_NEAR(s, swing, 0.1 * swing) << "the same beat each time";
  EXPECT_GT(swing, 0.05);
  // Half the pulse pressure, less swing (not half: the membrane stiffens as it stretches, 2.7 of
  // 3.5 mm here); a stiffer wall, less; none, still.
  const double half = beats_of(vessel_radius_mm(20.0, 2.6)).swing_mm.back();
  RecordProperty("swing_mm_half_pressure", std::to_string(half));
  EXPECT_GT(half, 0.3 * swing);
  EXPECT_LT(half, 0.9 * swing);
  const double stiff = beats_of(vessel_radius_mm(40.0, 2.6, 10.0)).swing_mm.back();
  RecordProperty("swing_mm_ten_times_stiffer", std::to_string(stiff));
  EXPECT_LT(stiff, 0.7 * swing);
  const double still = beats_of(vessel_radius_mm(0.0, 2.6)).swing_mm.back();
  EXPECT_LT(still, 0.05 * swing) << "without a pulse it keeps still";
}

TEST(Heartbeat, AProbeRestingOnTheVesselFeelsTheBeat) {
  // The probe comes to the vessel's anterior wall (-y) and rests 1.5 mm into it; the wall ten
  // times as stiff as the default scene's, whose soft membrane chatters under a resting probe.
  std::array<double, 2> beat_swing_N{};
  for (const bool pulse : {false, true}) {
    const SceneDescription scene = pulsing_scene(pulse ? 40.0 : 0.0, 10.0);
    SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
    const sim::SoftBody& vessel = sim.world().body(kVessel);
    glm::dvec3 front(0.0, 1e9, 0.0), centre(0.0);
    std::size_t n = 0;
    for (const glm::dvec3& p : vessel.positions()) {
      centre += p;
      ++n;
    }
    centre /= static_cast<double>(n);
    for (const glm::dvec3& p : vessel.positions()) {
      if (std::abs(p.z - centre.z) < 0.003 && p.y < front.y) front = p;
    }
    const glm::dvec3 front_mm = sim::sim_to_scene(front);
    for (int i = 0; i <= 300; ++i)
      (void)sim.tick(tip_at_mm(front_mm + glm::dvec3(0.0, -10.0 + 11.5 * i / 300.0, 0.0)));
    double lo = 1e9, hi = 0.0;
    for (int k = 0; k < 2000; ++k) {
      const double f = glm::length(sim.tick(tip_at_mm(front_mm + glm::dvec3(0, 1.5, 0))).force_N);
      if (k >= 1000) {
        lo = std::min(lo, f);
        hi = std::max(hi, f);
      }
    }
    ASSERT_GT(hi, 0.01) << "the probe rests on the wall";
    beat_swing_N[pulse ? 1 : 0] = hi - lo;
  }
  RecordProperty("force_swing_N", std::to_string(beat_swing_N[1]));
  EXPECT_GT(beat_swing_N[1], 0.02) << "the beat in the hand";
  EXPECT_GT(beat_swing_N[1], 10.0 * beat_swing_N[0]);
}

}  // namespace
}  // namespace bisturi::runtime
