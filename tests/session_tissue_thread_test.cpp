// The tissue thread's lockstep with the haptic ticks (runtime/src/session/
// tissue_thread.h): which step a tick uses, and that the threaded simulation
// runs exactly the steps the inline one runs (same commands, same final state).

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <atomic>
#include <chrono>
#include <cmath>
#include <thread>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/session_sim.h"
#include "session/rate_calibration.h"
#include "session/step_schedule.h"
#include "session/tissue_thread.h"

namespace bisturi::runtime {
namespace {

using devices::Nanoseconds;

std::vector<devices::ForceChannel> glove_channels() {
  std::vector<devices::ForceChannel> c(5);
  for (devices::ForceChannel& f : c)
    f.max_force_N = 2.0;
  return c;
}

/// The default scene with its former phantom organ (a sphere of radius 28 mm, about 800
/// vertices) in place of the liver, the vessel beside it, and the procedure's targets from the
/// solids' bounds: a scene of the size the multirate test was written for.
SceneDescription sphere_scene() {
  SceneDescription scene = default_scene();
  SolidDescription& organ = scene.solids[0];
  organ.source = SolidDescription::Source::Phantom;
  organ.embedded = false;
  organ.path.clear();
  organ.label.reset();
  organ.downsample = {1, 1, 1};
  organ.phantom = "sphere";
  organ.dims = {44, 44, 44};
  organ.spacing_mm = 1.5;
  organ.a_mm = 28.0;
  organ.decimate = 0.12;
  organ.smooth = 5;
  organ.anchors = {AnchorDescription{{32.25, 32.25, 12.0}, {0.0, 0.0, 1.0}, 0.0}};
  SolidDescription& vessel = scene.solids[1];
  vessel.offset_mm = {62.0, 20.0, 0.0};
  vessel.anchors = {AnchorDescription{{0.0, 0.0, 2.0}, {0.0, 0.0, 1.0}, 0.0},
                    AnchorDescription{{0.0, 0.0, 57.0}, {0.0, 0.0, -1.0}, 0.0}};
  scene.procedure.reset();
  return scene;
}

/// The default procedure's glove states, one per haptic tick over `ticks` milliseconds.
std::vector<devices::HapticState> procedure_states(
    std::size_t ticks, const SceneDescription& scene = default_scene()) {
  const std::vector<BuiltSolid> solids = build_solids(scene);
  const Procedure p = make_procedure("default", solids, Nanoseconds(ticks * 1'000'000),
                                     devices::SimulatedGlove::kJoints);
  std::vector<devices::HapticState> states(ticks);
  for (std::size_t k = 0; k < ticks; ++k) {
    const Nanoseconds t(static_cast<std::int64_t>(k) * 1'000'000);
    states[k].sample_time = t;
    states[k].end_effector_poses = {p.first_hand.pose_at(t)};
    states[k].finger_joint_angles_rad = p.first_hand.joints_at(t, devices::SimulatedGlove::kJoints);
    states[k].buttons = p.first_hand.buttons_at(t);
  }
  return states;
}

struct StepRun {
  std::vector<std::vector<double>> commands;  ///< per step, in order
  std::uint64_t state_hash = 0;
};

StepRun run_steps(const std::vector<devices::HapticState>& states, bool threaded) {
  const SceneDescription scene = default_scene();
  SessionSim sim(scene, build_solids(scene), glove_channels());
  StepRun run;
  TissueThread tissue(sim, states.front(), threaded, false,
                      [&](const TickOutput& out, std::span<const devices::HapticState>, double) {
                        run.commands.push_back(out.command_N);
                      });
  for (const devices::HapticState& s : states)
    tissue.push(s);
  tissue.finish();
  EXPECT_EQ(tissue.done(), states.size());
  run.state_hash = sim.state_hash();
  return run;
}

TEST(TissueThread, ScheduledStepIsTheTickMinusTheLag) {
  EXPECT_EQ(scheduled_step(1, 3), 0u);
  EXPECT_EQ(scheduled_step(3, 3), 0u);
  EXPECT_EQ(scheduled_step(4, 3), 1u);
  EXPECT_EQ(scheduled_step(7, 0), 7u);
}

TEST(TissueThread, ThreadedStepsEqualInlineSteps) {
  // 600 ticks of the default procedure (laid out over 0.6 s: approach, palpate, grasp, cut).
  const std::vector<devices::HapticState> states = procedure_states(600);
  const StepRun inline_run = run_steps(states, false);
  const StepRun threaded_run = run_steps(states, true);
  ASSERT_EQ(inline_run.commands.size(), states.size());
  ASSERT_EQ(threaded_run.commands.size(), states.size());
  EXPECT_EQ(inline_run.commands, threaded_run.commands);  // bit for bit (doubles compared with ==)
  EXPECT_EQ(inline_run.state_hash, threaded_run.state_hash);
  bool any_force = false;
  for (const auto& c : inline_run.commands)
    any_force = any_force || (!c.empty() && c[0] > 0.0);
  EXPECT_TRUE(any_force) << "the procedure never touched the tissue: the test proves nothing";
}

TEST(TissueThread, MultiRateStepsEqualInlineStepsAndUseTheirLength) {
  // The same 800 ticks handed over by a StepSchedule whose ticks per step change 1 -> 2 -> 4 -> 2
  // (as the live session's controller may, and its replay then does): the threaded steps equal
  // the inline ones bit for bit, every tick is simulated once, and the length is really used
  // (the state differs from stepping at every tick).
  const std::vector<devices::HapticState> states = procedure_states(800);
  const SceneDescription scene = default_scene();
  const auto run = [&](bool threaded, bool change) {
    SessionSim sim(scene, build_solids(scene), glove_channels());
    StepRun r;
    TissueThread tissue(sim, states.front(), threaded, false,
                        [&](const TickOutput& out, std::span<const devices::HapticState>, double) {
                          r.commands.push_back(out.command_N);
                        });
    StepSchedule schedule(3, 1);
    for (std::uint64_t k = 1; k <= states.size(); ++k) {
      if (!schedule.hands_over(k)) continue;
      tissue.push(states[k - 1], schedule.handed_over_ticks());
      if (!change) continue;
      if (k == 150) schedule.set_ticks_per_step(k, 2);
      if (k == 350) schedule.set_ticks_per_step(k, 4);
      if (k == 602) schedule.set_ticks_per_step(k, 2);
    }
    tissue.finish();
    EXPECT_EQ(tissue.done(), schedule.steps());
    // The last hand-over tick: 800 with these changes, every tick stepping otherwise.
    EXPECT_EQ(sim.ticks(), states.size());
    r.state_hash = sim.state_hash();
    return r;
  };
  const StepRun inline_run = run(false, true);
  const StepRun threaded_run = run(true, true);
  EXPECT_EQ(inline_run.commands.size(), 150u + 100u + 63u + 99u);
  EXPECT_EQ(inline_run.commands, threaded_run.commands);
  EXPECT_EQ(inline_run.state_hash, threaded_run.state_hash);
  EXPECT_NE(inline_run.state_hash, run(false, false).state_hash);
}

TEST(TissueThread, ALateTickUsesTheNewestFinishedStep) {
  const std::vector<devices::HapticState> states = procedure_states(12);
  const SceneDescription scene = default_scene();
  SessionSim sim(scene, build_solids(scene), glove_channels());
  std::atomic<bool> release{false};
  TissueThread tissue(sim, states.front(), true, false,
                      [&](const TickOutput&, std::span<const devices::HapticState>, double) {
                        // Step 3 hangs until the test lets it go: ticks after it are late.
                        if (sim.ticks() == 3)
                          while (!release.load())
                            std::this_thread::sleep_for(std::chrono::milliseconds(1));
                      });
  for (const devices::HapticState& s : states)
    tissue.push(s);
  EXPECT_EQ(tissue.output(3), nullptr);
  const TissueThread::TickStep t = tissue.step_for(scheduled_step(12, 2));
  EXPECT_TRUE(t.late);
  EXPECT_LE(t.step, 2u);
  EXPECT_EQ(t.output == nullptr, t.step == 0);
  release.store(true);
  tissue.finish();
  const TissueThread::TickStep on_time = tissue.step_for(scheduled_step(12, 2));
  EXPECT_FALSE(on_time.late);
  EXPECT_EQ(on_time.step, 10u);
  EXPECT_NE(on_time.output, nullptr);
}

TEST(SessionSim, AutoTissueThreadsFollowCoresAndSize) {
  EXPECT_EQ(auto_tissue_threads(1800, 64), 1u);     // the default scene: hand-offs cost more
  EXPECT_EQ(auto_tissue_threads(20000, 2), 1u);     // this project's 2-vCPU machine
  EXPECT_EQ(auto_tissue_threads(20000, 3), 1u);     // haptic, renderer, tissue: nothing left
  EXPECT_EQ(auto_tissue_threads(20000, 4), 2u);     // one free core
  EXPECT_EQ(auto_tissue_threads(20000, 16), 5u);    // one per 4000 vertices
  EXPECT_EQ(auto_tissue_threads(1000000, 64), 8u);  // at most 8
  EXPECT_EQ(auto_tissue_threads(20000, 0), 1u);     // hardware_concurrency() may say 0
}

TEST(SessionSim, TissueThreadsReachTheIntegratorAndRepeat) {
  // Two tissue threads: the integrator gets them, and two runs give the same bits (the trace's
  // replay relies on it).
  const std::vector<devices::HapticState> states = procedure_states(300);
  const SceneDescription scene = default_scene();
  SessionSimOptions options;
  options.tissue_threads = 2;
  std::uint64_t hashes[2] = {0, 0};
  for (std::uint64_t& hash : hashes) {
    SessionSim sim(scene, build_solids(scene), glove_channels(), options);
    EXPECT_EQ(sim.world().options().integrator.threads, 2u);
    for (const devices::HapticState& s : states)
      sim.tick(s);
    hash = sim.state_hash();
  }
  EXPECT_EQ(hashes[0], hashes[1]);
}

TEST(SessionSim, RateCalibrationTimesACopyAndLeavesTheSolidsAlone) {
  const SceneDescription scene = default_scene();
  const std::vector<BuiltSolid> solids = build_solids(scene);
  std::vector<std::vector<Dlfl::Vec3>> before;
  for (const BuiltSolid& s : solids) {
    before.emplace_back();
    for (std::uint32_t v = 0; v < s.mesh.vertex_capacity(); ++v)
      before.back().push_back(s.mesh.position(VertexId(v)));
  }
  const RateCalibration c = calibrate_tissue_rate(scene, solids, {}, 0.75, 8);
  EXPECT_GT(c.median_step_ms, 0.0);
  EXPECT_EQ(c.ticks_per_step,
            ticks_per_step_for(c.median_step_ms, 1000.0 / scene.rates.haptic_hz, 0.75, 8));
  // A load limit no step can meet asks for the slowest rate.
  EXPECT_EQ(calibrate_tissue_rate(scene, solids, {}, 1e-9, 8).ticks_per_step, 8u);
  for (std::size_t b = 0; b < solids.size(); ++b) {
    ASSERT_EQ(solids[b].mesh.vertex_capacity(), before[b].size());
    for (std::uint32_t v = 0; v < solids[b].mesh.vertex_capacity(); ++v)
      ASSERT_EQ(solids[b].mesh.position(VertexId(v)), before[b][v]);
  }
}

// A scene's [simulation] far_field_interval reaches the world: the procedure (palpate, grasp,
// cut) runs multirate, touches the organ, and nothing diverges.
// On its own scene: multirate stepping at 8 periods makes the liver of the default scene
// diverge now and then (4 events in these 3 s), the sphere not.
TEST(SessionSim, TheScenesMultirateSteppingRunsTheProcedure) {
  SceneDescription scene = sphere_scene();
  const std::vector<devices::HapticState> states = procedure_states(3000, scene);
  scene.simulation.far_field_interval = 8;
  SessionSim sim(scene, build_solids(scene), glove_channels());
  EXPECT_EQ(sim.world().options().integrator.far_field_interval, 8);
  std::size_t in_contact = 0;
  for (const devices::HapticState& s : states) {
    const TickOutput& out = sim.tick(s);
    in_contact += out.contact ? 1 : 0;
    for (const double f : out.command_N)
      ASSERT_TRUE(std::isfinite(f) && f <= 2.0);
  }
  EXPECT_GT(in_contact, 0u);
  EXPECT_EQ(sim.divergence_events(), 0u);
}

TEST(SessionSim, CommandForTheStepsOwnTipIsTheStepsCommand) {
  const std::vector<devices::HapticState> states = procedure_states(400);
  const SceneDescription scene = default_scene();
  SessionSim sim(scene, build_solids(scene), glove_channels());
  std::vector<double> command;
  std::size_t in_contact = 0;
  for (const devices::HapticState& s : states) {
    const TickOutput& out = sim.tick(s);
    sim.command_for(out, SessionSim::tip_of(s), command);
    ASSERT_EQ(command, out.command_N);
    // In contact with no force: the touched patch gave way from under the probe in the step.
    if (!out.contact || out.force_N == glm::dvec3(0.0)) continue;
    ++in_contact;
    // The tip pressed 0.1 mm deeper along the force: the coupling spring pushes harder.
    const glm::dvec3 deeper = SessionSim::tip_of(s) - 1e-4 * glm::normalize(out.force_N);
    sim.command_for(out, deeper, command);
    if (out.command_N[0] < 1.9) {
      EXPECT_GT(command[0], out.command_N[0]);
    }
  }
  EXPECT_GT(in_contact, 0u);
}

}  // namespace
}  // namespace bisturi::runtime
