#pragma once
// The headset session (the seed's figure 33 as threads):
//  - haptic thread, at the scene's haptic rate: simulated twins send their reports (they stand in
//    for hardware that sends on its own), the drivers read them over the virtual transport, or
//    over hidapi/libusb for real devices (SessionDevices) -> on a hand-over tick the haptic state
//    goes to the tissue thread as the next step (StepSchedule: every tick, or every n-th when
//    the tissue steps at a fraction of the haptic rate) -> the command of the step due
//    (`tissue_lag_ticks` ticks back, plus n - 1), its proxy force corrected for the tip's motion
//    since (SessionSim::command_for) -> GuardedHaptic (force guard) -> the haptic device's driver
//    -> the trace; the head pose goes to the renderer through a TripleBuffer;
//  - tissue thread (TissueThread): SessionSim::tick on every handed-over haptic state in order
//    (instruments, collision, proxy, soft-tissue step over n periods), then a snapshot
//    (positions per solid, topology, instrument poses, events) into a TripleBuffer;
//  - render thread, at the headset's rate: takes the newest snapshot and head pose ->
//    StereoRenderer -> sink (OpenXR when a runtime is there, PNG files otherwise);
//  - the calling thread only starts, watches (progress callback) and stops them.
// Nothing waits on the renderer, and the haptic thread waits on nothing. Why the tissue has its
// own thread (measured on the 2-core machine with the renderer running): the step alone is
// 0.2-0.6 ms, but a cut's topology change costs 2-6 ms and steps near contacts reach 1-5 ms
// when the renderer's threads compete, so inside the tick they missed 14-65 deadlines in 10 s.
// On a slower machine (a 2-core Zen 1 VM: the default scene's step takes 0.8-1.0 ms) 1 kHz steps
// could not keep up at all (the tissue fell 1.2 s behind); the rate controller
// (TissueRateController) settles there at 250-500 Hz.
// All times come from one injectable devices::Clock (SteadyClock live).

#include <array>
#include <atomic>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/runtime/session/fault_injection.h"
#include "bisturi/runtime/session/headset_report.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/runtime/session/timing.h"

namespace bisturi::runtime {

struct SessionProgress {
  double elapsed_s = 0.0;
  double duration_s = 0.0;
  std::uint64_t ticks = 0;
  std::uint64_t frames = 0;
  std::uint64_t overruns = 0;
  std::size_t events = 0;
  double force_N = 0.0;  ///< proxy force on the tip now
  std::string stage;     ///< "build", "start", "run"
  /// Set on the first update after an input went dead (the haptic device sent nothing for a
  /// second): what to tell the user; empty otherwise.
  std::string warning;
};

struct SessionOptions {
  /// Overrides the scene's duration_s.
  std::optional<double> duration_s;
  /// Folder for frames (PNG + frames.csv); empty: frames are rendered but not written.
  std::filesystem::path frames_dir;
  /// Write every n-th frame's image (frames.csv has every frame).
  std::uint32_t image_every = 1;
  /// Trace file to record into; empty: no recording.
  std::filesystem::path record;
  std::optional<std::uint32_t> eye_width;
  std::optional<std::uint32_t> eye_height;
  /// Try OpenXR first; without a runtime the PNG sink is used (the report says why).
  bool openxr = true;
  render::DevicePreference render_device = render::DevicePreference::Any;
  /// Leave out of each frame what the solids in front hide (RendererOptions::occlusion_cells).
  bool occlusion_culling = false;
  /// The haptic thread sleeps until this long before each deadline, then spins (0: sleep only).
  /// Adaptive: at most this long, as long as its wakeups have lately run late (wakeup_spin.h).
  double spin_us = 200.0;
  bool adaptive_spin = true;
  /// Ask for SCHED_FIFO for the haptic thread and, just below it, the tissue thread (kept
  /// quietly when refused).
  bool realtime_priority = true;
  /// Run the soft-tissue step on its own thread, `tissue_lag_ticks` ticks behind the haptic
  /// loop; false: inside the haptic tick (lag 0), for comparison.
  bool tissue_thread = true;
  std::uint32_t tissue_lag_ticks = 3;
  /// Haptic ticks one tissue step covers at the start (its time step is that many periods; the
  /// step runs on the haptic state of its last tick). See step_schedule.h.
  std::uint32_t tissue_ticks_per_step = 1;
  /// Let the session double the ticks per step (up to max_tissue_ticks_per_step) when the steps
  /// take longer than 3/4 of the time they cover, and halve it again when there is room; each
  /// change is written into the trace. false: the ticks per step stay fixed.
  bool adaptive_tissue_rate = true;
  std::uint32_t max_tissue_ticks_per_step = 8;
  /// The share of the time a step covers that it may take before the rate halves.
  double tissue_max_load = 0.75;
  /// Blood steps the blood's thread may fall behind before the blood's clock stops (slow
  /// motion, noted in the trace), until it is back within half that: the tissue never waits.
  std::uint32_t blood_hold_at = 4;
  /// Threads of the soft-tissue step (the tissue thread plus helpers); 0: auto_tissue_threads.
  /// Recorded in the trace: the state's bits depend on it.
  std::uint32_t tissue_threads = 0;
  /// The session's clock; nullptr: devices::steady_clock().
  devices::Clock* clock = nullptr;
  /// Called from the calling thread about ten times a second, and for start-up stages.
  std::function<void(const SessionProgress&)> progress;
  /// Set (e.g. by a SIGINT/SIGTERM handler) to end the session early and cleanly: forces zeroed
  /// first, the trace sealed, the report complete (ending "interrupted").
  const std::atomic<bool>* stop_requested = nullptr;
  /// Faults to make happen at their session times (fault_injection.h), in any order.
  std::vector<InjectedFault> inject;
};

struct SolidReport {
  std::string name;
  std::size_t vertices = 0;
  std::size_t faces = 0;
  double build_ms = 0.0;
  std::string model = "surface";  ///< "surface" (a spring membrane) or "volume"
  std::size_t volume_cells = 0;   ///< a volume's hexahedra, and their nodes
  std::size_t volume_nodes = 0;
  double volume_build_ms = 0.0;  ///< the volume's lattice, elements and embedding
  /// A refined box that follows the instrument: how often it moved, and its longest rebuild.
  std::uint64_t volume_refocuses = 0;
  double volume_longest_refocus_ms = 0.0;
  /// Lattice faces the cuts separated (the wound's walls in the volume).
  std::size_t volume_separated_faces = 0;
  /// The share of the tissue's steps the volume slept through (at rest, untouched: skipped).
  double volume_asleep_share = 0.0;
  /// A finer drawn surface riding on the volume ([solids.drawn]; 0 vertices: the simulated
  /// surface is drawn): its size, build time (surface, embedding and closest points), and how
  /// far it was from the simulated surface at rest and, at most, in any frame drawn (mm).
  std::size_t drawn_vertices = 0;
  std::size_t drawn_faces = 0;
  double drawn_build_ms = 0.0;
  double drawn_rest_gap_mm = 0.0;
  double drawn_most_gap_mm = 0.0;
  /// Cuts made on the drawn surface, and those its surface gave no path for (drawn uncut).
  std::uint64_t drawn_cuts = 0;
  std::uint64_t drawn_cuts_missed = 0;
};

/// A vessel that pulses with the heartbeat: its lumen pressure over the beat.
struct PulseReport {
  std::string solid;
  double diastolic_mmHg = 0.0;
  double systolic_mmHg = 0.0;
};

struct EventReport {
  SessionEvent event;
  double time_s = 0.0;  ///< since the session started
  /// From the device report that carried the action to the first frame that shows it; negative
  /// when no frame showed it before the session ended.
  double response_ms = -1.0;
};

/// A solid's step that diverged (SessionSim::divergences), for the report.
struct DivergenceReport {
  double time_s = 0.0;
  std::uint64_t tick = 0;
  std::string body;     ///< the solid's name
  bool frozen = false;  ///< the solid was frozen (else the step was rolled back and retried)
  int substeps = 1;     ///< of the attempt that failed
  std::string reason;   ///< "energy rose by ...", "non-finite state", "vertex ... faster than"
};

struct ForceSample {
  double t_s = 0.0;
  double proxy_N = 0.0;    ///< magnitude of the proxy force on the tip
  double command_N = 0.0;  ///< the first actuator's command (before the guard)
  double output_N = 0.0;   ///< what the guard let through to it
};

struct SessionReport {
  std::string scene;
  double duration_s = 0.0;
  double haptic_hz = 0.0;
  double display_hz = 0.0;
  std::uint32_t eye_width = 0, eye_height = 0;
  std::string render_device;
  bool render_device_is_cpu = false;
  std::string sink;       ///< "openxr" or "png"
  std::string sink_note;  ///< why OpenXR was not used
  bool realtime_priority = false;
  bool tissue_in_haptic_thread = false;
  std::uint32_t tissue_lag_ticks = 0;
  /// Ticks whose step (tick - lag) was not finished in time: they used the newest finished one.
  std::uint64_t late_ticks = 0;
  /// Most steps the tissue thread was behind the haptic loop at a tick.
  std::uint64_t max_tissue_backlog = 0;
  bool adaptive_tissue_rate = false;
  /// Haptic ticks per tissue step: at the start (with an adaptive rate, from the median of a
  /// few timed steps, calibration_step_ms), at the end, the most used, and how often it changed.
  std::uint32_t first_tissue_ticks_per_step = 1;
  double calibration_step_ms = 0.0;  ///< 0: not calibrated (fixed rate); -1: it failed
  std::string calibration_error;
  std::uint32_t tissue_ticks_per_step = 1;
  std::uint32_t max_tissue_ticks_per_step = 1;
  std::uint64_t tissue_rate_changes = 0;
  std::uint32_t tissue_threads = 1;
  std::vector<SolidReport> solids;
  std::vector<std::string> devices;  ///< "glove: hid-glove (simulated)"
  /// The heartbeat in force: its rate and the vessels it pulses (none: no pulse); the breathing:
  /// its period and the solids it moves, each with its displacement at full inspiration (mm).
  double heart_rate_bpm = 0.0;
  std::vector<PulseReport> pulsing;
  double breathing_period_s = 0.0;
  std::vector<std::pair<std::string, std::array<double, 3>>> breathing;
  /// Bleeding (sim/blood.h): the blood's particles at the end (emitted = in flight + pooled +
  /// drained + recycled), the volume that left the vessels, the most particles in the field at
  /// once, each blood step's wall time on the blood's thread, and how far that thread fell
  /// behind the tissue (SessionSim::BloodLag); how often and for how long (simulated seconds)
  /// the blood's clock stopped because its thread was blood_hold_at steps behind.
  struct Bleeding {
    std::uint64_t emitted = 0, in_flight = 0, pooled = 0, drained = 0;
    double volume_ml = 0.0;
    std::uint64_t most_particles = 0;
    std::uint64_t recycled = 0;
    std::uint64_t most_behind_steps = 0, tissue_waits = 0;
    double tissue_waited_ms = 0.0;
    std::uint64_t hold_at_steps = 0, holds = 0;
    double held_s = 0.0;
    std::uint32_t threads = 1;  ///< threads that step the blood
  } bleeding;
  TimingRecorder blood_step_ms{"ms"};
  /// What the renderer drew and left out, per frame on average, in the frames before the first
  /// cut and in those after it (render::FrameStats), with each window's render time.
  struct Culling {
    std::uint64_t frames = 0;
    double draw_calls = 0.0;
    double triangles_submitted = 0.0;
    double culled_frustum = 0.0;
    double culled_occlusion = 0.0;
    double culled_portal = 0.0;
    TimingRecorder render_ms{"ms"};
  };
  Culling before_cut, after_cut;
  /// Structures inside the solids ([[solids.inner]]): name, the solid they lie in, size.
  struct Inner {
    std::string name, solid;
    std::size_t vertices = 0, faces = 0;
  };
  std::vector<Inner> inner;
  /// The drape and the field's ambient occlusion, computed at start (ms).
  double field_shading_ms = 0.0;
  /// The hands: the scene names of the haptic devices, in hand order (an event's hand indexes it).
  std::vector<std::string> hands;

  std::uint64_t ticks = 0;
  std::uint64_t frames = 0;
  std::uint64_t images = 0;
  double render_fps = 0.0;

  TimingRecorder haptic_period_ms{"ms"};
  TimingRecorder haptic_period_error_ms{"ms"};  ///< |period - nominal|
  TimingRecorder tick_ms{"ms"};                 ///< the whole tick's work
  TimingRecorder step_ms{"ms"};  ///< SessionSim::tick (instruments + tissue), its own thread
  /// The steps among those that cut (a topology change): how long the force waited on a cut.
  TimingRecorder cut_step_ms{"ms"};
  TimingRecorder frame_ms{"ms"};   ///< between frames handed to the renderer
  TimingRecorder render_ms{"ms"};  ///< update + render() call
  TimingRecorder motion_to_photon_ms{"ms"};
  TimingRecorder action_to_response_ms{"ms"};
  /// The haptic thread: how late each sleep before a tick ended, and the spin then (us).
  TimingRecorder haptic_wake_late_us{"us"};
  TimingRecorder haptic_spin_us{"us"};

  std::uint64_t overruns = 0;          ///< ticks whose work took longer than the period
  std::uint64_t missed_deadlines = 0;  ///< ticks that ended after the next tick was due
  /// Missed deadlines of ticks whose own work took under half a period: the thread was woken
  /// late (compare tools/bench/timer_bench: the machine's own floor).
  std::uint64_t missed_by_late_wakeup = 0;
  /// The tick of each missed deadline, in order (kept up to the room reserved before the
  /// session: a tenth of its ticks), and the tick of the step that made the first cut (-1: no
  /// cut): the deadlines missed before the cut and after it (missed_around_first_cut), with
  /// and without the bleeding that follows a cut in one run.
  std::vector<std::uint64_t> missed_deadline_ticks;
  std::int64_t first_cut_tick = -1;
  std::uint64_t skipped_ticks = 0;   ///< periods dropped when the loop fell behind
  std::uint64_t clamped_forces = 0;  ///< force guard clamps
  std::uint64_t rate_limited_forces = 0;
  std::uint64_t guard_latches = 0;   ///< steps on which the guard latched (watchdog, NaN, ...)
  std::uint64_t dropped_frames = 0;  ///< display refreshes without a new frame
  std::uint64_t malformed_reports = 0;
  std::uint64_t divergence_events = 0;
  /// Hand-overs the tissue could not queue (a whole ring behind); the ticks then used older steps.
  std::uint64_t dropped_tissue_steps = 0;
  /// Stalled ticks whose output the supervisor zeroed (past the period plus the guard's margin).
  std::uint64_t supervisor_zeros = 0;
  /// Ticks whose step was older than the due one by more than stale_margin_ticks: their force
  /// faded to zero. The longest such run, in ticks.
  std::uint64_t stale_ticks = 0;
  std::uint64_t longest_stale_run = 0;
  std::uint32_t stale_margin_ticks = 0;
  /// Ticks on which the command slew held a channel to the device's rate limit.
  std::uint64_t slewed_ticks = 0;
  /// The haptic device silent (no report for 100 ms; its forces are zero then): in all, and the
  /// longest stretch; and how long the force guard was latched (zero output), in seconds.
  double haptic_silent_s = 0.0;
  double haptic_longest_silence_s = 0.0;
  double guard_latched_s = 0.0;
  /// The haptic device not tracked (a controller its runtime lost; its forces are zero then):
  /// in all, and the longest stretch, in seconds.
  double haptic_untracked_s = 0.0;
  double haptic_longest_untracked_s = 0.0;
  /// How long the instrument's tip was away from the solids (outside their box widened by half
  /// its size on every side), in seconds.
  double instrument_outside_scene_s = 0.0;
  /// How long the haptic device's clutch was held (its instrument still, its forces zero).
  double haptic_clutched_s = 0.0;
  /// What the session ignored that the user should know (an instrument that touched nothing,
  /// that spent the session away from the organs): also printed at the end.
  std::vector<std::string> warnings;
  /// Session time the haptic device / head tracker was lost (-1: never) and why. A lost haptic
  /// device's force is zero and its instrument holds its pose; a lost tracker's view holds.
  double haptic_device_lost_s = -1.0;
  std::string haptic_device_lost_reason;
  double head_tracker_lost_s = -1.0;
  std::string head_tracker_lost_reason;
  /// Why the recording stopped before the end (empty: it did not, or nothing was recorded).
  std::string recording_error;
  /// Each injected fault (SessionOptions::inject, in time order) and what followed it.
  std::vector<FaultOutcome> injected;
  /// How the session ended: "completed" (its duration), "interrupted" (stop_requested),
  /// "headset" (the OpenXR runtime ended it early: the user exited or the runtime went away;
  /// headset.stop_reason says which) or "error" (the renderer or the soft tissue failed; `error`
  /// says what). The report is whole in every case.
  std::string ending;
  std::string error;
  std::vector<EventReport> events;
  /// The first SessionSim::kKeptDivergences of divergence_events.
  std::vector<DivergenceReport> divergences;
  std::vector<ForceSample> force;
  double max_force_N = 0.0;
  /// Whether the haptic device's writes return within a bound (false for hidapi's hid_write:
  /// a device that holds off keeps the tick waiting, and only the supervisor's zero goes out).
  bool haptic_write_bounded = true;
  std::uint64_t final_state_hash = 0;
  std::filesystem::path trace;
  HeadsetReport headset;
};

/// The soft-tissue step's thread count for solids of `simulated_vertices` vertices in all on a
/// machine with `cores` hardware threads: the cores the haptic loop (which spins), the renderer and
/// the tissue thread leave free become helpers, one per 4000 vertices (smaller bodies lose more to
/// the hand-offs than the parts save), at most 8. 1 on a machine with 3 cores or fewer.
std::uint32_t auto_tissue_threads(std::size_t simulated_vertices, unsigned cores);

/// Runs a live session of `scene`. Throws at set-up only: SceneFileError, devices::DeviceError /
/// TraceError (a device or the trace cannot be opened). Once the session runs, every ending
/// returns a whole report (see SessionReport::ending).
SessionReport run_session(const SceneDescription& scene, const SessionOptions& options);

/// A report's missed deadlines before its first cut and from it on (all before when there was
/// no cut), from the ticks it kept (SessionReport::missed_deadline_ticks).
struct MissedAroundCut {
  std::uint64_t before = 0;
  std::uint64_t after = 0;
  std::uint64_t ticks_before = 0;  ///< haptic ticks before the cut
  std::uint64_t ticks_after = 0;
};
MissedAroundCut missed_around_first_cut(const SessionReport& report);

/// The configuration a session writes into its trace (JSON): the force guard's settings and the
/// scene's TOML text, so a replay rebuilds the same session from the trace alone. The first
/// haptic device's trace index goes under the key "glove_device", the trace format's name for it.
std::string session_trace_config(const std::string& scene_toml,
                                 const std::filesystem::path& base_dir, double haptic_hz,
                                 std::uint16_t haptic_device, std::uint32_t tissue_lag_ticks,
                                 std::uint32_t tissue_ticks_per_step = 1,
                                 std::uint32_t tissue_threads = 1);

}  // namespace bisturi::runtime
