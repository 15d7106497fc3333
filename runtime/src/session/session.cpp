// The headset session: haptic thread, render thread, hand-off and timing (see session.h).

#include "bisturi/runtime/session/session.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <exception>
#include <fstream>
#include <limits>
#include <memory>
#include <nlohmann/json.hpp>
#include <sstream>
#include <stdexcept>
#include <thread>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>

#include "bisturi/devices/controller/openxr_controller.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/devices/virtual_transport.h"
#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/instrument_mesh.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/session_devices.h"
#include "bisturi/runtime/session/triple_buffer.h"
#include "bisturi/runtime/version.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/volume/volume_body.h"
#include "drawn_surface.h"
#include "fault_injector.h"
#include "haptic_loop.h"
#include "haptic_thread.h"
#include "lockstep_notes.h"
#include "owned_thread.h"
#include "rate_calibration.h"
#include "render_loop.h"
#include "session_snapshot.h"
#include "step_schedule.h"
#include "tissue_thread.h"

namespace bisturi::runtime {

namespace {

using devices::Nanoseconds;

double ms(Nanoseconds d) {
  return static_cast<double>(d.count()) * 1e-6;
}

render::PoseClock::time_point to_pose_clock(Nanoseconds t) {
  return render::PoseClock::time_point(std::chrono::duration_cast<render::PoseClock::duration>(t));
}

std::string read_text(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::stringstream s;
  s << in.rdbuf();
  return s.str();
}

/// The session's trace (null when not recording): its header holds the scene's text and the
/// settings a replay needs.
std::unique_ptr<devices::TraceWriter> open_session_trace(const SceneDescription& scene,
                                                         const SessionOptions& options,
                                                         devices::Clock& clock, std::uint32_t lag,
                                                         std::uint32_t ticks_per_step,
                                                         std::uint32_t tissue_threads) {
  if (options.record.empty()) return nullptr;
  const std::string toml =
      scene.file.empty() ? std::string(default_scene_toml()) : read_text(scene.file);
  devices::TraceHeader header;
  header.start_time_ns = clock.now().count();
  header.wall_clock_unix_ns =
      std::chrono::duration_cast<Nanoseconds>(std::chrono::system_clock::now().time_since_epoch())
          .count();
  header.producer = std::string("bisturi ") + kVersion;
  // The hands' devices are opened first, in order: hand h is device h of the trace.
  header.config = session_trace_config(
      toml, scene.file.empty() ? std::filesystem::path() : scene.file.parent_path(),
      scene.rates.haptic_hz, 0, lag, ticks_per_step, tissue_threads);
  // The haptic tick records: a disk that falls behind stops the recording, never the tick.
  devices::TraceWriterOptions writer_options;
  writer_options.wait_when_full = false;
  return std::make_unique<devices::TraceWriter>(options.record, header, writer_options);
}

/// What the haptic loop counted, into the report: each hand's device figures summed (the
/// longest runs the longest of any hand, a loss the first hand's to be lost).
void add_loop_counters(const HapticLoop& loop, SessionReport& report) {
  const HapticLoopCounters& c = loop.counters();
  report.late_ticks = c.late_ticks;
  report.max_tissue_backlog = c.max_tissue_backlog;
  report.tissue_rate_changes = c.tissue_rate_changes;
  report.max_tissue_ticks_per_step =
      std::max(report.max_tissue_ticks_per_step, c.max_ticks_per_step);
  report.tissue_ticks_per_step = loop.schedule().ticks_per_step();
  report.dropped_tissue_steps = c.dropped_steps;
  report.stale_ticks = c.stale_ticks;
  report.longest_stale_run = c.longest_stale_run;
  report.malformed_reports = c.head_malformed_reports;
  const double period_s = 1.0 / report.haptic_hz;
  const auto s = [period_s](std::uint64_t ticks) { return static_cast<double>(ticks) * period_s; };
  for (const HandCounters& h : c.hands) {
    report.malformed_reports += h.malformed_reports;
    report.guard_latches += h.guard_latches;
    report.supervisor_zeros += h.supervisor_zeros;
    report.slewed_ticks += h.slewed_ticks;
    report.haptic_silent_s += s(h.silent_ticks);
    report.haptic_longest_silence_s =
        std::max(report.haptic_longest_silence_s, s(h.longest_silence_ticks));
    report.guard_latched_s += s(h.guard_latched_ticks);
    report.haptic_untracked_s += s(h.untracked_ticks);
    report.haptic_longest_untracked_s =
        std::max(report.haptic_longest_untracked_s, s(h.longest_untracked_ticks));
    report.instrument_outside_scene_s += s(h.outside_scene_ticks);
    report.haptic_clutched_s += s(h.clutched_ticks);
    if (h.lost_s >= 0.0 &&
        (report.haptic_device_lost_s < 0.0 || h.lost_s < report.haptic_device_lost_s)) {
      report.haptic_device_lost_s = h.lost_s;
      report.haptic_device_lost_reason = h.lost_reason;
    }
  }
  report.head_tracker_lost_s = c.head_lost_s;
  report.head_tracker_lost_reason = c.head_lost_reason;
  report.recording_error = c.recording_error;
  report.headset.ticks_without_display = c.display_held_ticks;
  report.headset.display_stalls = c.display_stalls;
}

}  // namespace

std::string session_trace_config(const std::string& scene_toml,
                                 const std::filesystem::path& base_dir, double haptic_hz,
                                 std::uint16_t haptic_device, std::uint32_t tissue_lag_ticks,
                                 std::uint32_t tissue_ticks_per_step,
                                 std::uint32_t tissue_threads) {
  devices::ForceGuardConfig guard;
  guard.period = Nanoseconds{static_cast<std::int64_t>(std::llround(1e9 / haptic_hz))};
  nlohmann::json j = nlohmann::json::parse(devices::force_guard_config_json(guard));
  j["session"] = {{"scene_toml", scene_toml},
                  {"base_dir", base_dir.string()},
                  {"haptic_hz", haptic_hz},
                  {"glove_device", haptic_device},  // the trace format's name
                  {"tissue_lag_ticks", tissue_lag_ticks},
                  {"tissue_ticks_per_step", tissue_ticks_per_step},
                  {"tissue_threads", tissue_threads},
                  {"producer", std::string("bisturi ") + kVersion}};
  return j.dump();
}

std::uint32_t auto_tissue_threads(std::size_t simulated_vertices, unsigned cores) {
  constexpr unsigned kBusyThreads = 3;  // haptic loop, renderer, tissue thread
  constexpr std::size_t kVerticesPerThread = 4000;
  constexpr std::uint32_t kMostThreads = 8;
  const std::uint32_t free_cores = cores > kBusyThreads ? cores - kBusyThreads : 0;
  const std::size_t by_size = simulated_vertices / kVerticesPerThread;
  return std::clamp<std::uint32_t>(
      static_cast<std::uint32_t>(std::min<std::size_t>(by_size, free_cores + 1)), 1, kMostThreads);
}

namespace {

/// What the watching thread says about one hand's device, each once: dead inputs within a
/// second (the forces are zero meanwhile: the guard latched), and a guard that keeps latching.
struct HandWatch {
  std::string device;  ///< "'left' (vendor-arm)"
  std::string name;    ///< "'left'"
  int silence_limit_ms = 0;
  bool warned_silent = false;
  bool warned_untracked = false;
  bool warned_latching = false;
  std::uint64_t latches_at_window = 0;
  static constexpr std::uint64_t kLatchesToWarn = 3;

  /// The warning due now for hand h (empty: none); `window_over`: a second of latches counted.
  std::string look(const HapticLoop& loop, std::size_t h, bool window_over) {
    std::string said;
    const double silent_s = loop.silent_for_s(h);
    if (silent_s >= 1.0 && !warned_silent) {
      said = "the haptic device " + device + " has sent nothing for " +
             std::to_string(static_cast<int>(silent_s)) +
             " s: its forces are zero until it reports again";
    }
    warned_silent = silent_s >= 1.0;
    const double untracked_s = loop.untracked_for_s(h);
    if (untracked_s >= 0.5 && !warned_untracked) {
      // A controller whose grip the runtime never located (none bound, switched off, out of
      // view) says so here, not only in the report.
      said = "the haptic device " + device + " has not been tracked for " +
             std::to_string(static_cast<int>(untracked_s * 1000.0)) +
             " ms: its instrument holds still and its forces are zero until it is";
    }
    warned_untracked = untracked_s >= 0.5;
    // A guard that keeps latching zeros the force again and again: the device's reports come
    // late or irregularly (a controller at a slow display rate, a loaded bus).
    if (window_over) {
      const std::uint64_t latches = loop.guard_latches_now(h);
      if (latches - latches_at_window >= kLatchesToWarn && !warned_latching && said.empty()) {
        said = "the force guard of " + name + " latched " +
               std::to_string(latches - latches_at_window) +
               " times in the last second, zeroing its forces each time: its reports come late "
               "or irregularly, or the ticks ran late (its silence limit is " +
               std::to_string(silence_limit_ms) + " ms)";
        warned_latching = true;
      }
      latches_at_window = latches;
    }
    return said;
  }
};

/// A hand whose instrument touched nothing, or spent half a second or more away from the
/// solids, is named in the report's warnings.
void warn_what_was_ignored(SessionReport& report, const HapticLoopCounters& counters,
                           const DeviceChoice& choice) {
  const double ran_s = static_cast<double>(report.ticks) / report.haptic_hz;
  const auto seconds_text = [](double s) {
    char text[32];
    std::snprintf(text, sizeof text, "%.1f s", s);
    return std::string(text);
  };
  for (std::size_t h = 0; h < choice.hands.size(); ++h) {
    const std::string& device = choice.hands[h]->name;
    const bool touched =
        std::any_of(report.events.begin(), report.events.end(), [h](const EventReport& e) {
          return e.event.kind == SessionEventKind::Contact && e.event.hand == h;
        });
    if (!touched && ran_s >= 1.0) {
      report.warnings.push_back("the instrument of '" + device + "' touched nothing in " +
                                seconds_text(ran_s) +
                                ": is the device where the scene expects it "
                                "(device_to_scene_rotation_deg, device_to_scene_translation_mm)?");
    }
    const double outside_s =
        h < counters.hands.size()
            ? static_cast<double>(counters.hands[h].outside_scene_ticks) / report.haptic_hz
            : 0.0;
    if (outside_s >= 0.5) {
      report.warnings.push_back("the instrument of '" + device + "' was away from the solids for " +
                                seconds_text(outside_s) + " of " + seconds_text(ran_s) +
                                " (outside their box widened by half its size)");
    }
  }
}

}  // namespace

SessionReport run_session(const SceneDescription& scene, const SessionOptions& options) {
  devices::Clock& clock = options.clock != nullptr ? *options.clock : devices::steady_clock();
  SessionReport report;
  report.scene = scene.name;
  report.duration_s = options.duration_s.value_or(scene.duration_s);
  report.haptic_hz = scene.rates.haptic_hz;
  report.display_hz = std::min(scene.rates.display_hz, scene.headset.refresh_hz);
  report.eye_width =
      options.eye_width.value_or(static_cast<std::uint32_t>(scene.headset.eye_width));
  report.eye_height =
      options.eye_height.value_or(static_cast<std::uint32_t>(scene.headset.eye_height));
  SessionProgress progress;
  progress.duration_s = report.duration_s;
  const auto stage = [&](const std::string& name) {
    progress.stage = name;
    if (options.progress) options.progress(progress);
  };

  // ---- The scene's solids and devices ----
  const DeviceChoice choice = choose_session_devices(scene);
  const std::uint32_t lag = options.tissue_thread ? options.tissue_lag_ticks : 0;
  report.tissue_in_haptic_thread = !options.tissue_thread;
  report.tissue_lag_ticks = lag;
  std::uint32_t first_ticks_per_step = std::max(1u, options.tissue_ticks_per_step);
  report.adaptive_tissue_rate = options.adaptive_tissue_rate;
  stage("build");
  std::vector<BuiltSolid> solids = build_solids(scene);
  std::size_t simulated_vertices = 0;
  for (const BuiltSolid& s : solids) {
    report.solids.push_back(
        {s.description->name, s.mesh.num_vertices(), s.mesh.num_faces(), s.build_ms});
    if (s.description->simulate) simulated_vertices += s.mesh.num_vertices();
  }
  report.tissue_threads =
      options.tissue_threads > 0
          ? options.tissue_threads
          : auto_tissue_threads(simulated_vertices, std::thread::hardware_concurrency());
  SessionSimOptions sim_options;
  sim_options.tissue_threads = report.tissue_threads;
  if (options.adaptive_tissue_rate) {
    // The first rate from a few timed steps of a copy (rate_calibration.h); the trace records
    // the rate chosen, so a replay does not depend on this machine's timing.
    // A copy that does not build (it should, from a built solid) leaves the rate where it was:
    // the controller still adapts it.
    stage("timing the tissue step");
    try {
      const RateCalibration calibration = calibrate_tissue_rate(
          scene, solids, sim_options, options.tissue_max_load, options.max_tissue_ticks_per_step);
      report.calibration_step_ms = calibration.median_step_ms;
      first_ticks_per_step = std::max(first_ticks_per_step, calibration.ticks_per_step);
    } catch (const std::exception& e) {
      report.calibration_step_ms = -1.0;
      report.calibration_error = e.what();
    }
  }
  report.first_tissue_ticks_per_step = first_ticks_per_step;
  report.tissue_ticks_per_step = first_ticks_per_step;
  report.max_tissue_ticks_per_step = first_ticks_per_step;
  const auto duration =
      Nanoseconds{static_cast<std::int64_t>(std::llround(report.duration_s * 1e9))};
  const devices::Registry registry = devices::builtin_registry();
  // Each hand's script presses the buttons its driver says cut and grasp. The procedure is
  // written in scene coordinates; a twin moves as its device would where the scene puts it (the
  // session brings its poses back through device_to_scene).
  const auto hand_buttons = [&](const DeviceDescription& d) {
    const devices::DriverInfo* driver = registry.find_by_name(d.driver);
    return driver != nullptr ? driver->layout.buttons : std::vector<devices::ButtonUse>{};
  };
  const auto script_of = [](const DeviceDescription& d) {
    return d.simulated ? d.script : std::string("default");
  };
  Procedure procedure =
      make_procedure(script_of(*choice.haptic), solids, duration, devices::SimulatedGlove::kJoints,
                     hand_buttons(*choice.haptic));
  procedure.first_hand =
      device_frame_of(*choice.haptic).script_to_device(std::move(procedure.first_hand));
  for (std::size_t h = 1; h < choice.hands.size(); ++h) {
    const DeviceDescription& d = *choice.hands[h];
    procedure.other_hands.push_back(device_frame_of(d).script_to_device(make_hand_script(
        script_of(d), solids, duration, devices::SimulatedGlove::kJoints, hand_buttons(d))));
  }

  std::unique_ptr<devices::TraceWriter> writer =
      open_session_trace(scene, options, clock, lag, first_ticks_per_step, report.tissue_threads);
  if (writer) report.trace = options.record;
  // A hand controller the headset tracks is fed by the render thread (render_loop.h).
  devices::ControllerFeed controller_feed;
  SessionDevices session_devices(
      scene, procedure, registry, clock, writer.get(),
      [&](const devices::DriverInfo& driver) { return controller_feed.open_for(driver); });
  devices::Tracker* head = &session_devices.head();
  report.devices = session_devices.summary();
  for (const DeviceDescription* hand : choice.hands)
    report.hands.push_back(hand->name);
  report.heart_rate_bpm = scene.physiology.heart_rate_bpm;
  for (const SolidDescription& s : scene.solids) {
    if (s.pulse_mmHg) report.pulsing.push_back({s.name, (*s.pulse_mmHg)[0], (*s.pulse_mmHg)[1]});
    if (s.breathing_mm) report.breathing.emplace_back(s.name, *s.breathing_mm);
  }
  report.breathing_period_s = scene.physiology.breathing_period_s;
  devices::ForceGuardConfig guard_config = devices::force_guard_config_from_json(
      session_trace_config("", {}, scene.rates.haptic_hz, 0, lag));
  report.max_force_N = choice.haptic->max_force_N;
  for (std::size_t h = 0; h < session_devices.hand_count(); ++h) {
    if (session_devices.haptic_write_bounded(h)) continue;
    report.haptic_write_bounded = false;
    if (!options.progress) continue;
    SessionProgress said;
    said.stage = "start";
    said.warning = "the haptic device '" + choice.hands[h]->name +
                   "' is written through a transport without a bounded write (hidapi): a device "
                   "that stops taking reports holds the haptic tick, and no zero reaches it "
                   "before it takes reports again";
    options.progress(said);
  }

  // One hand per haptic device, each with its own force guard.
  std::vector<HandSetup> hand_setups;
  for (std::size_t h = 0; h < session_devices.hand_count(); ++h) {
    devices::HapticDevice& device = session_devices.haptic(h);
    hand_setups.push_back({device.capabilities().force_channels, device_frame_of(*choice.hands[h]),
                           device.capabilities().spec, session_devices.haptic_channels(h),
                           session_devices.haptic_buttons(h), choice.hands[h]->max_force_N});
  }
  SessionSim sim(scene, std::move(solids), hand_setups, sim_options);
  for (std::uint32_t b = 0; b < report.solids.size(); ++b) {
    if (const sim::VolumeBody* volume = sim.world().volume(b)) {
      SolidReport& s = report.solids[b];
      s.model = "volume";
      s.volume_cells = volume->volume().lattice().cells.size();
      s.volume_nodes = volume->volume().lattice().rest.size();
      s.volume_build_ms = sim.volume_build_ms(b);
    }
  }
  std::vector<std::unique_ptr<devices::ForceGuard>> guards;
  std::vector<std::unique_ptr<devices::GuardedHaptic>> guarded;
  for (std::size_t h = 0; h < session_devices.hand_count(); ++h) {
    guards.push_back(std::make_unique<devices::ForceGuard>(sim.guard_channels(h), guard_config));
    guarded.push_back(std::make_unique<devices::GuardedHaptic>(
        session_devices.haptic(h), *guards.back(), clock, writer.get(),
        session_devices.haptic_trace_index(h)));
  }

  // ---- The hand-off ----
  const Snapshot initial = initial_snapshot(sim);
  // Solids drawn finer than they are simulated ride on their volumes (drawn_surface.h).
  const std::string scene_name = scene.file.empty() ? "default scene" : scene.file.string();
  std::vector<std::unique_ptr<DrawnSurface>> drawn(scene.solids.size());
  for (std::uint32_t b = 0; b < scene.solids.size(); ++b) {
    if (!scene.solids[b].drawn || !initial.solids[b].lattice) continue;
    stage("build drawn surface");
    const auto start = std::chrono::steady_clock::now();
    std::optional<Dlfl> mesh = build_drawn_surface(scene.solids[b], scene_name);
    drawn[b] = std::make_unique<DrawnSurface>(std::move(*mesh), &sim.world().body(b),
                                              initial.solids[b].lattice);
    SolidReport& s = report.solids[b];
    s.drawn_build_ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
    s.drawn_vertices = drawn[b]->vertices();
    s.drawn_faces = drawn[b]->faces();
    s.drawn_rest_gap_mm = drawn[b]->rest_gap_mm();
    s.drawn_most_gap_mm = s.drawn_rest_gap_mm;
  }
  // The drape under the field and how much of the sky each part sees (field_occlusion.h).
  std::vector<const Dlfl*> drawn_meshes(scene.solids.size(), nullptr);
  for (std::size_t b = 0; b < drawn.size(); ++b)
    if (drawn[b]) drawn_meshes[b] = &drawn[b]->mesh();
  stage("shading the field");
  const FieldShading shading = shade_field(sim.world(), drawn_meshes, kDrapeBelow_mm);
  report.field_shading_ms = shading.build_ms;
  // The structures inside them ride on their volumes too, drawn only where they can be seen.
  std::vector<InnerStructure> inner;
  for (std::uint32_t b = 0; b < scene.solids.size(); ++b) {
    if (scene.solids[b].inner.empty() || !initial.solids[b].lattice) continue;
    stage("build inner structures");
    for (const SolidDescription& d : scene.solids[b].inner) {
      InnerStructure in{b, d.material.colour,
                        std::make_unique<DrawnSurface>(build_solid(d, scene_name), nullptr,
                                                       initial.solids[b].lattice)};
      report.inner.push_back(
          {d.name, scene.solids[b].name, in.surface->vertices(), in.surface->faces()});
      inner.push_back(std::move(in));
    }
  }
  TripleBuffer<Snapshot> handoff(initial);
  TripleBuffer<render::HeadPose> head_handoff;

  std::atomic<bool> stop{false};
  std::atomic<bool> render_ready{false};
  std::atomic<std::uint64_t> ticks{0}, frames{0}, overruns{0};
  std::atomic<double> force_now{0.0};
  std::string render_error;
  std::atomic<bool> interrupted{false};
  const auto wall_start = std::chrono::steady_clock::now();
  std::vector<Nanoseconds> event_times;  // written by the tissue thread, read after the join...
  event_times.reserve(4096);             // ...and by the render thread below its published count
  std::vector<double> event_response(4096, -1.0);
  std::atomic<bool> realtime{false};
  Nanoseconds t0{0};

  // ---- Tissue thread: each step publishes the snapshot the renderer draws ----
  SnapshotPublisher publisher(sim, initial, handoff, event_times);
  // Injected faults: the tissue thread and the renderer act on theirs (fault_injector.h).
  FaultInjector faults(options.inject, report, clock, session_devices, writer.get(),
                       scene.rates.haptic_hz);
  faults.controller_fed = controller_feed.opened();
  sim.stall_blood_when(
      &faults.stall_blood,
      std::chrono::milliseconds(static_cast<std::int64_t>(kBloodStallSeconds * 1000.0)));
  const auto publish_step = [&](const TickOutput& out, std::span<const devices::HapticState> states,
                                double step_ms) {
    report.step_ms.record(step_ms);
    if (out.topology_changed) report.cut_step_ms.record(step_ms);
    publisher.publish(out, states);
    if (faults.fail_tissue.exchange(false))
      throw std::runtime_error("injected fault: tissue-throw");
    if (faults.hang_tissue.exchange(false))
      std::this_thread::sleep_for(std::chrono::duration<double>(kFaultHangSeconds));
  };
  std::vector<devices::HapticState> hand_shapes(session_devices.hand_count());
  for (std::size_t h = 0; h < hand_shapes.size(); ++h) {
    const devices::Capabilities& caps = session_devices.haptic(h).capabilities();
    hand_shapes[h].end_effector_poses.resize(caps.end_effectors);
    hand_shapes[h].finger_joint_angles_rad.resize(caps.finger_joints.size());
  }
  TissueThread tissue(sim, hand_shapes, options.tissue_thread, options.realtime_priority,
                      publish_step);

  // ---- Render thread ----
  std::atomic<bool> display_live{true};  // false while a headset shows nothing: no forces
  std::atomic<std::int64_t> display_deadline_ns{-1};  // when the renderer must come round by
  OwnedThread render_thread(
      [&] {
        try {
          run_render_loop({scene,
                           options,
                           report,
                           initial,
                           handoff,
                           head_handoff,
                           stop,
                           render_ready,
                           frames,
                           event_response,
                           event_times,
                           display_live,
                           writer.get(),
                           controller_feed.opened() ? &controller_feed : nullptr,
                           &faults.fail_render,
                           &faults.hang_render,
                           &faults.lose_controller,
                           &faults.stall_swapchain,
                           &faults.headset_sink,
                           &display_deadline_ns,
                           &drawn,
                           &inner,
                           &shading});
        } catch (const std::exception& e) {
          render_error = e.what();
          render_ready.store(true);
          stop.store(true);
        } catch (...) {
          render_error = "unknown error";
          render_ready.store(true);
          stop.store(true);
        }
      },
      [&] { stop.store(true); });

  // ---- Haptic thread: paces the ticks of the one haptic loop (haptic_loop.h) ----
  const Nanoseconds period{static_cast<std::int64_t>(std::llround(1e9 / scene.rates.haptic_hz))};
  const Nanoseconds spin{static_cast<std::int64_t>(options.spin_us * 1e3)};
  report.force.reserve(static_cast<std::size_t>(report.duration_s * 200.0) + 16);
  report.missed_deadline_ticks.reserve(
      static_cast<std::size_t>(report.duration_s * scene.rates.haptic_hz / 10.0) + 16);
  LiveTickSteps steps(tissue, options.adaptive_tissue_rate,
                      TissueRateController(first_ticks_per_step, options.max_tissue_ticks_per_step,
                                           ms(period), options.tissue_max_load));
  steps.blood_hold_at = std::max<std::uint32_t>(1, options.blood_hold_at);
  HapticLoopParts parts;
  parts.stale_margin_ticks = static_cast<std::uint32_t>(scene.simulation.stale_margin_ticks);
  report.stale_margin_ticks = parts.stale_margin_ticks;
  for (std::size_t h = 0; h < session_devices.hand_count(); ++h) {
    parts.hands.push_back(
        {guarded[h].get(), hand_setups[h].device_frame,
         devices::buttons_with(session_devices.haptic_buttons(h), devices::ButtonUse::Clutch)});
  }
  parts.steps = &steps;
  parts.sim = &sim;
  parts.clock = &clock;
  parts.writer = writer.get();
  parts.head = head;
  parts.step_twins = [&](Nanoseconds t) { session_devices.step_twins(t); };
  parts.display_live = &display_live;
  parts.display_deadline_ns = &display_deadline_ns;
  // The solids' box at the start, widened by half its size on every side: the instrument comes
  // from outside, but not from across the room.
  {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(std::numeric_limits<double>::lowest());
    for (const SolidState& solid : initial.solids) {
      for (const glm::dvec3& p_mm : solid.positions_mm) {
        lo = glm::min(lo, sim::scene_to_sim(p_mm));
        hi = glm::max(hi, sim::scene_to_sim(p_mm));
      }
    }
    if (lo.x <= hi.x) {
      parts.scene_box_min_m = lo - 0.5 * (hi - lo);
      parts.scene_box_max_m = hi + 0.5 * (hi - lo);
    }
  }
  parts.head_state = [&](const devices::TrackerState& hs) {
    // The head pose straight to the renderer (motion-to-photon starts at its sample).
    render::HeadPose& hp = head_handoff.back();
    hp.position_mm = sim::sim_to_scene(glm::dvec3(
        hs.head_pose.position_m.x, hs.head_pose.position_m.y, hs.head_pose.position_m.z));
    hp.orientation = glm::dquat(hs.head_pose.orientation.w, hs.head_pose.orientation.x,
                                hs.head_pose.orientation.y, hs.head_pose.orientation.z);
    hp.sample_time = to_pose_clock(hs.sample_time);
    head_handoff.publish();
  };
  HapticLoop loop(std::move(parts), lag, first_ticks_per_step);
  HapticPacing pacing;
  pacing.period = period;
  pacing.spin = spin;
  pacing.adaptive_spin = options.adaptive_spin;
  pacing.duration = duration;
  pacing.realtime_priority = options.realtime_priority;
  pacing.stop_requested = options.stop_requested;
  HapticThreadFlags flags{stop, render_ready, interrupted, realtime, ticks, overruns, force_now};
  faults.watch_with(flags);
  // Unwinding, the haptic thread is told to stop and the output goes to zero first.
  OwnedThread haptic_thread([&] { run_haptic_thread(loop, clock, pacing, flags, report, t0); },
                            [&] {
                              stop.store(true);
                              loop.stop();
                            });

  // ---- Supervisor: zero within the watchdog's limit when a tick stalls ----
  const Nanoseconds stall_limit = period + guard_config.deadline_margin;
  std::atomic<bool> supervising{true};
  OwnedThread supervisor(
      [&] {
        while (supervising.load(std::memory_order_relaxed)) {
          std::this_thread::sleep_for(std::chrono::microseconds(250));
          if (loop.zero_if_stalled(clock.now(), stall_limit)) faults.zero_went_out(clock.now());
        }
      },
      [&] { supervising.store(false); });

  // ---- The calling thread watches (and makes the injected faults happen) ----
  progress.stage = "run";
  std::vector<HandWatch> watches;
  for (std::size_t h = 0; h < session_devices.hand_count(); ++h) {
    watches.push_back(
        {"'" + choice.hands[h]->name + "' (" + session_devices.haptic(h).driver_name() + ")",
         "'" + choice.hands[h]->name + "'",
         static_cast<int>(ms(guard_config.device_silence_timeout))});
  }
  auto latch_window_start = std::chrono::steady_clock::now();
  auto last_progress = wall_start;
  while (!stop.load()) {
    // With faults to inject the watch is finer: each happens within a few milliseconds of its time.
    std::this_thread::sleep_for(std::chrono::milliseconds(faults.any() ? 2 : 100));
    faults.poll(ticks.load());
    if (std::chrono::steady_clock::now() - last_progress < std::chrono::milliseconds(100)) continue;
    last_progress = std::chrono::steady_clock::now();
    if (options.stop_requested != nullptr && options.stop_requested->load())
      interrupted.store(true);
    progress.elapsed_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
    progress.ticks = ticks.load();
    progress.frames = frames.load();
    progress.overruns = overruns.load();
    progress.events = publisher.events();
    progress.force_N = force_now.load();
    progress.warning.clear();
    const bool latch_window_over =
        std::chrono::steady_clock::now() - latch_window_start >= std::chrono::seconds(1);
    for (std::size_t h = 0; h < watches.size(); ++h) {
      const std::string said = watches[h].look(loop, h, latch_window_over);
      if (!said.empty()) progress.warning += (progress.warning.empty() ? "" : "; ") + said;
    }
    if (latch_window_over) latch_window_start = std::chrono::steady_clock::now();
    if (options.progress) options.progress(progress);
  }
  haptic_thread.join();
  faults.finish();
  supervising.store(false);
  supervisor.join();
  loop.stop();  // already done by the haptic thread; kept in case it never started its loop
  // The steps still queued run to the last tick, so the final state is that of every tick.
  std::string tissue_error;
  try {
    tissue.finish();
  } catch (const std::exception& e) {
    tissue_error = e.what();
  }
  stop.store(true);
  render_thread.join();

  // ---- The session ends: final state, devices closed (zero forces), trace closed ----
  add_loop_counters(loop, report);
  report.ticks = ticks.load();  // haptic ticks (the tissue may have stepped fewer times)
  report.overruns = overruns.load();
  report.realtime_priority = realtime.load();
  report.final_state_hash = sim.state_hash();
  for (std::uint32_t b = 0; b < report.solids.size(); ++b) {
    if (const sim::VolumeBody* volume = sim.world().volume(b)) {
      report.solids[b].volume_refocuses = volume->refocus_count();
      report.solids[b].volume_longest_refocus_ms = volume->longest_refocus_ms();
      report.solids[b].volume_separated_faces = volume->separated_faces();
      report.solids[b].volume_asleep_share =
          volume->steps() > 0
              ? static_cast<double>(volume->asleep_steps()) / static_cast<double>(volume->steps())
              : 0.0;
    }
  }
  {
    const sim::BloodCounts& c = sim.blood().counts();
    report.bleeding = {c.emitted,
                       c.in_flight,
                       c.pooled,
                       c.drained,
                       sim.blood().emitted_ml(),
                       sim.blood_most_particles(),
                       c.recycled};
    const SessionSim::BloodLag behind = sim.blood_lag();
    report.bleeding.most_behind_steps = behind.most_behind_steps;
    report.bleeding.tissue_waits = behind.tissue_waits;
    report.bleeding.tissue_waited_ms = behind.tissue_waited_ms;
    report.bleeding.hold_at_steps = steps.blood_hold_at;
    report.bleeding.holds = loop.counters().blood_holds;
    report.bleeding.held_s = sim.blood_held_s();
    report.bleeding.threads = sim.blood_threads();
    for (const double step : sim.blood_step_ms())
      report.blood_step_ms.record(step);
  }
  for (const auto& guard : guards) {
    report.clamped_forces += guard->clamp_count();
    report.rate_limited_forces += guard->rate_limit_count();
  }
  report.divergence_events = sim.divergence_events();
  for (const Divergence& d : sim.divergences()) {
    report.divergences.push_back(
        {static_cast<double>(d.tick) / scene.rates.haptic_hz, d.tick, sim.body_name(d.event.body),
         d.event.kind == bisturi::sim::SimEventKind::Frozen, d.event.substeps, d.event.reason});
  }
  report.render_fps = report.frames > 1 && report.frame_ms.count() > 0
                          ? 1000.0 / report.frame_ms.summary().mean
                          : 0.0;
  for (std::size_t i = 0; i < sim.events().size(); ++i) {
    EventReport e;
    e.event = sim.events()[i];
    e.time_s = static_cast<double>(e.event.tick) / scene.rates.haptic_hz;
    if (i < event_response.size()) e.response_ms = event_response[i];
    report.events.push_back(std::move(e));
  }
  warn_what_was_ignored(report, loop.counters(), choice);
  // Every ending writes the closing note and closes the devices and the trace; a failure there
  // is reported, not thrown, so the report is written either way.
  try {
    if (writer && writer->failure().empty()) {
      const nlohmann::json end = {{"session_end",
                                   {{"ticks", report.ticks},
                                    {"state_hash", report.final_state_hash},
                                    {"events", report.events.size()}}}};
      writer->note(clock.now().count(), end.dump());
    }
  } catch (const std::exception& e) {
    if (report.recording_error.empty()) report.recording_error = e.what();
  }
  session_devices.close();
  if (writer) {
    try {
      writer->close();
    } catch (const std::exception& e) {
      if (report.recording_error.empty()) report.recording_error = e.what();
    }
    if (report.recording_error.empty()) report.recording_error = writer->failure();
  }
  if (!render_error.empty()) {
    report.ending = "error";
    report.error = "renderer: " + render_error;
  } else if (!tissue_error.empty()) {
    report.ending = "error";
    report.error = "soft tissue: " + tissue_error;
  } else if (interrupted.load()) {
    report.ending = "interrupted";
  } else if (!report.headset.stop_reason.empty()) {
    report.ending = "headset";
  } else {
    report.ending = "completed";
  }
  return report;
}

}  // namespace bisturi::runtime
