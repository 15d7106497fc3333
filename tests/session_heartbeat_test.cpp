// The body's own motion through the session's simulation. The heartbeat (sim/pulse.h): the phantom
// scene's vessel with a lumen pressure of 80/120 mmHg at 72 beats a minute pulses at that
// period, by an amount a wall of its stiffness gives, and a probe resting on it feels the beat.
// A step that diverges is kept with its tick, solid and reason for the report.
// Breathing: the phantom organ's anchored base carried up and back over each breath, the organ
// following through its volume, and a probe held still feeling it come up.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
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

/// The phantom scene (a sphere and a tube, config/phantom.toml).
SceneDescription phantom_scene() {
  return read_scene_file(std::string(BISTURI_SOURCE_DIR) + "/config/phantom.toml");
}

/// The phantom scene, its vessel's wall `stiffer` times as stiff, pulsing from 80 mmHg to
/// 80 + pulse_mmHg (none at 0).
SceneDescription pulsing_scene(double pulse_mmHg, double stiffer = 1.0) {
  SceneDescription scene = phantom_scene();
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
  // times as stiff as the phantom scene's, whose soft membrane chatters under a resting probe.
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

constexpr std::size_t kOrgan = 0;

/// The default organ breathing `breathing_mm` over 2 s: its free surface's centroid (mm) each
/// tick for `seconds`, the probe resting `press_mm` into its top (none when negative), and the
/// probe's force each tick.
struct Breath {
  std::vector<glm::dvec3> centroid_mm;
  std::vector<double> force_N;
  std::uint64_t divergence_events = 0;
};
Breath breathe(const glm::dvec3& breathing_mm, double seconds, double press_mm) {
  SceneDescription scene = phantom_scene();
  scene.physiology.breathing_period_s = 2.0;
  if (breathing_mm != glm::dvec3(0.0))
    scene.solids.at(kOrgan).breathing_mm = {breathing_mm.x, breathing_mm.y, breathing_mm.z};
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  const sim::SoftBody& organ = sim.world().body(kOrgan);
  glm::dvec3 top(0.0, 0.0, -1e9);
  for (const glm::dvec3& p : organ.positions())
    if (p.z > top.z) top = p;
  const glm::dvec3 top_mm = sim::sim_to_scene(top);
  Breath b;
  const auto ticks = static_cast<int>(seconds * scene.rates.haptic_hz);
  for (int k = 0; k < ticks; ++k) {
    // The probe comes down over the first 200 ms, then rests.
    const double above = press_mm < 0.0 ? 40.0 : std::max(-press_mm, 10.0 - 0.05 * k);
    const TickOutput& out = sim.tick(tip_at_mm(top_mm + glm::dvec3(0.0, 0.0, above)));
    b.force_N.push_back(glm::length(out.force_N));
    glm::dvec3 c(0.0);
    std::size_t n = 0;
    for (std::size_t i = 0; i < organ.positions().size(); ++i) {
      if (organ.masses()[i] <= 0.0) continue;
      c += organ.positions()[i];
      ++n;
    }
    b.centroid_mm.push_back(sim::sim_to_scene(c / static_cast<double>(n)));
  }
  b.divergence_events = sim.divergence_events();
  return b;
}

TEST(SessionSimDivergence, AStepThatDivergesIsKeptWithItsTickSolidAndReason) {
  const SceneDescription scene = pulsing_scene(40.0);
  SessionSim sim(scene, build_solids(scene), std::vector<devices::ForceChannel>{});
  const devices::HapticState away = tip_at_mm({0.0, 0.0, 500.0});
  for (int i = 0; i < 10; ++i)
    (void)sim.tick(away);
  ASSERT_EQ(sim.divergence_events(), 0u);
  ASSERT_TRUE(sim.divergences().empty());
  // A force no step can take: every retry in substeps fails and the vessel freezes.
  sim::SoftBody& vessel = sim.world().body(kVessel);
  std::uint32_t v = 0;
  while (vessel.masses()[v] <= 0.0)
    ++v;
  vessel.add_force(VertexId(v), glm::dvec3(std::numeric_limits<double>::quiet_NaN()));
  (void)sim.tick(away);
  ASSERT_GE(sim.divergence_events(), 2u);
  ASSERT_EQ(sim.divergences().size(), sim.divergence_events());
  for (const Divergence& d : sim.divergences()) {
    EXPECT_EQ(d.tick, 10u);
    EXPECT_EQ(d.event.body, kVessel);
    EXPECT_FALSE(d.event.reason.empty());
  }
  EXPECT_EQ(sim.divergences().front().event.kind, sim::SimEventKind::RolledBack);
  EXPECT_NE(sim.divergences().front().event.reason.find("non-finite"), std::string::npos)
      << sim.divergences().front().event.reason;
  EXPECT_EQ(sim.divergences().back().event.kind, sim::SimEventKind::Frozen);
  // Frozen: no more divergences, and the count and the list agree.
  for (int i = 0; i < 10; ++i)
    (void)sim.tick(away);
  EXPECT_EQ(sim.divergences().size(), sim.divergence_events());
}

TEST(Breathing, TheOrganRisesAndFallsWithEachBreath) {
  // 10 mm up at full inspiration (1 s, 3 s), back at the end of expiration (2 s, 4 s), against
  // the same organ not breathing (its sag under gravity subtracted).
  const Breath still = breathe(glm::dvec3(0.0), 4.2, -1.0);
  const Breath breathing = breathe(glm::dvec3(0.0, 0.0, 10.0), 4.2, -1.0);
  const auto lift_at = [&](double t_s) {
    const auto k = static_cast<std::size_t>(std::lround(t_s * 1000.0)) - 1;
    return breathing.centroid_mm[k] - still.centroid_mm[k];
  };
  RecordProperty("lift_mm_at_inspiration", std::to_string(lift_at(3.0).z));
  for (const double inspiration : {1.0, 3.0}) {
    EXPECT_NEAR(lift_at(inspiration).z, 10.0, 1.0) << inspiration << " s";
    EXPECT_NEAR(lift_at(inspiration).x, 0.0, 0.5);
  }
  for (const double expiration : {2.0, 4.0})
    EXPECT_NEAR(lift_at(expiration).z, 0.0, 1.0) << expiration << " s";
  EXPECT_EQ(breathing.divergence_events, 0u);
}

TEST(Breathing, AProbeHeldStillFeelsTheOrganComeUpAgainstIt) {
  const Breath b = breathe(glm::dvec3(0.0, 0.0, 4.0), 3.2, 1.0);
  const auto force_at = [&](double t_s) {
    return b.force_N[static_cast<std::size_t>(std::lround(t_s * 1000.0)) - 1];
  };
  RecordProperty("force_N_expiration", std::to_string(force_at(2.0)));
  RecordProperty("force_N_inspiration", std::to_string(force_at(3.0)));
  EXPECT_GT(force_at(2.0), 0.0) << "resting on the organ at the end of expiration";
  EXPECT_GT(force_at(3.0), 2.0 * force_at(2.0)) << "pressed harder as it breathes in";
  EXPECT_EQ(b.divergence_events, 0u);
}

TEST(Breathing, OnlyAVolumeWithAnchorsBreathes) {
  const std::string membrane = R"(
[[solids]]
name = "vessel"
phantom = "tube"
breathing_mm = [0.0, 0.0, 5.0]
[[solids.anchors]]
point_mm = [0.0, 0.0, 2.0]
normal = [0.0, 0.0, 1.0]
)";
  try {
    (void)parse_scene(membrane, "breathing.toml");
    FAIL() << "a membrane was given breathing";
  } catch (const SceneFileError& e) {
    EXPECT_NE(std::string(e.what()).find("solids[0].breathing_mm"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("model = \"volume\""), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bisturi::runtime
