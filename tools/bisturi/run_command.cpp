#include "run_command.h"

#include <signal.h>
#include <CLI/CLI.hpp>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iostream>
#include <nlohmann/json.hpp>
#include <sstream>

#include "bisturi/devices/trace/trace_format.h"
#include "bisturi/runtime/session/plots.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/session_replay.h"
#include "progress_line.h"

namespace bisturi::cli {

namespace {

nlohmann::json summary_json(const runtime::TimingRecorder& r) {
  const runtime::TimingSummary s = r.summary();
  return {{"unit", r.unit()}, {"count", s.count}, {"mean", s.mean}, {"p50", s.p50},
          {"p95", s.p95},     {"p99", s.p99},     {"max", s.max},   {"min", s.min}};
}

/// The number `text` spells, all of it; nothing when it is not one.
std::optional<double> number_in(const std::string& text) {
  try {
    std::size_t used = 0;
    const double value = std::stod(text, &used);
    if (used == text.size()) return value;
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

std::string hex(std::uint64_t v) {
  std::ostringstream s;
  s << "0x" << std::hex << std::setw(16) << std::setfill('0') << v;
  return s.str();
}

}  // namespace

void add_run_command(CLI::App& app, RunOptions& options, int (*&run)(const RunOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "run",
      "run a headset session (the default scene without SCENE): haptics at the scene's rate, "
      "stereo frames at the headset's, written with report.json and plots into --out");
  cmd->add_option("SCENE", options.scene, "scene file (TOML, see config/liver.toml)")
      ->check(CLI::ExistingFile);
  cmd->add_option("--duration", options.duration_s, "seconds (default: the scene's duration_s)")
      ->check(CLI::Range(0.05, 3600.0));
  cmd->add_option("--record", options.record, "record the session's device trace into TRACE");
  cmd->add_option("--out", options.out, "folder for frames, report.json and plots")
      ->capture_default_str();
  cmd->add_option("--eye-width", options.eye_width, "pixels per eye, across (default: the scene's)")
      ->check(CLI::Range(16u, 8192u));
  cmd->add_option("--eye-height", options.eye_height, "pixels per eye, down (default: the scene's)")
      ->check(CLI::Range(16u, 8192u));
  cmd->add_option("--image-every", options.image_every,
                  "write every n-th frame as PNG (frames.csv lists every frame)")
      ->capture_default_str()
      ->check(CLI::Range(1u, 100000u));
  cmd->add_flag("--no-openxr", options.no_openxr, "do not try an OpenXR headset");
  cmd->add_flag("--cpu", options.cpu, "render on a CPU Vulkan device (lavapipe) even with a GPU");
  cmd->add_flag("--occlusion", options.occlusion,
                "leave out what the solids in front hide (occlusion culling on the CPU)");
  cmd->add_flag("--tissue-in-haptic-thread", options.tissue_in_haptic_thread,
                "run the soft-tissue step inside the haptic tick instead of on its own thread "
                "(for comparison)");
  cmd->add_option("--tissue-lag", options.tissue_lag_ticks,
                  "haptic ticks the tissue thread may take for a step before a tick counts late")
      ->capture_default_str()
      ->check(CLI::Range(1u, 1000u));
  cmd->add_option("--tissue-hz", options.tissue_hz,
                  "soft-tissue step rate: `auto` starts at the haptic rate and halves it (down to "
                  "an eighth) while the steps take more than 3/4 of their time on this machine, "
                  "doubling it again when there is room; a number fixes it (it must divide the "
                  "haptic rate); the haptic loop stays at its rate and corrects the force for the "
                  "hand's motion in between")
      ->capture_default_str();
  cmd->add_option("--tissue-max-load", options.tissue_max_load,
                  "with --tissue-hz auto: the share of the time a step covers that it may take on "
                  "the tissue thread before the rate halves (the rest of the core is the "
                  "renderer's)")
      ->capture_default_str()
      ->check(CLI::Range(0.001, 1.0));
  cmd->add_option("--blood-hold-at", options.blood_hold_at,
                  "blood steps the blood's thread may fall behind before the blood's clock "
                  "stops (slow motion, noted in the trace) until it has caught up half way: the "
                  "tissue's thread, and through it the force, never waits for the blood")
      ->capture_default_str()
      ->check(CLI::Range(1u, 16u));
  cmd->add_option("--tissue-threads", options.tissue_threads,
                  "threads of the soft-tissue step: `auto` gives it the cores that the haptic "
                  "loop, the renderer and the tissue thread leave free, one per 4000 vertices "
                  "(1 on this kind of 2-core machine); a number (1-64) fixes it. The trace "
                  "records it, and the replay uses the same count: the state's bits depend on it")
      ->capture_default_str();
  cmd->add_option("--haptic-spin", options.haptic_spin,
                  "microseconds the haptic thread spins before each tick after it sleeps: "
                  "`auto` spins as long as its wakeups have lately come late (the 99th "
                  "percentile of the last 512, plus 10 us; from 20 to 200 us), so the cores "
                  "keep the rest; a number (0-1000, 0: sleep only) fixes it")
      ->capture_default_str();
  cmd->add_option("--inject", options.inject,
                  "make a fault happen at a session time, FAULT@SECONDS (repeatable), to check "
                  "that the force reaches zero and the report says so: " +
                      runtime::fault_names() +
                      " (hangs and stalls last 2 s); report.json's faults.injected gives, per "
                      "fault, the time to zero force on every channel");
  cmd->add_flag("--print-default-scene", options.print_default_scene,
                "print the embedded default scene (TOML) and exit");
  cmd->add_flag("--json", options.json, "write the report as one JSON object on stdout");
  cmd->callback([&run] { run = run_run; });
}

void add_replay_command(CLI::App& app, ReplayOptions& options, int (*&run)(const ReplayOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "replay",
      "rerun a session recorded with `bisturi run --record` in virtual time and check that the "
      "forces sent and the final state match the recording (exit status 2 when not)");
  cmd->add_option("TRACE", options.trace, "trace file (.btrace)")
      ->required()
      ->check(CLI::ExistingFile);
  cmd->add_flag("--json", options.json, "write the result as one JSON object on stdout");
  cmd->callback([&run] { run = run_replay; });
}

namespace {

/// report.json for a session that never started (a bad scene file, a device not connected, a
/// trace that cannot be written): the ending, the stage and the error, so a script reading the
/// report always finds one. Best effort: a folder that cannot be written is the error itself.
void write_setup_failure(const std::filesystem::path& out, const std::string& scene,
                         const std::string& error) {
  try {
    std::filesystem::create_directories(out);
    const nlohmann::json report = {{"scene", scene},
                                   {"ending", "error"},
                                   {"stage", "setup"},
                                   {"error", error},
                                   {"out", out.string()}};
    std::ofstream(out / "report.json") << report.dump(2) << "\n";
  } catch (const std::exception&) {
  }
}

}  // namespace

int run_run(const RunOptions& options) {
  if (options.print_default_scene) {
    std::cout << runtime::default_scene_toml();
    return 0;
  }
  const std::filesystem::path out(options.out);
  runtime::SceneDescription scene;
  try {
    scene =
        options.scene.empty() ? runtime::default_scene() : runtime::read_scene_file(options.scene);
  } catch (const std::exception& e) {
    write_setup_failure(out, options.scene, e.what());
    throw;
  }
  std::filesystem::create_directories(out);

  runtime::SessionOptions so;
  so.duration_s = options.duration_s;
  so.frames_dir = out / "frames";
  so.image_every = options.image_every;
  so.record = options.record;
  so.eye_width = options.eye_width;
  so.eye_height = options.eye_height;
  so.openxr = !options.no_openxr;
  so.tissue_thread = !options.tissue_in_haptic_thread;
  so.tissue_lag_ticks = options.tissue_lag_ticks;
  so.tissue_max_load = options.tissue_max_load;
  so.blood_hold_at = options.blood_hold_at;
  if (options.tissue_hz != "auto") {
    const double hz = number_in(options.tissue_hz).value_or(0.0);
    const double ratio = hz > 0.0 ? scene.rates.haptic_hz / hz : 0.0;
    const long n = std::lround(ratio);
    if (!(hz > 0.0) || n < 1 || n > 1000 || std::abs(ratio - static_cast<double>(n)) > 1e-9)
      throw std::invalid_argument("--tissue-hz " + options.tissue_hz +
                                  ": give `auto` or a rate that divides the haptic rate (" +
                                  (std::ostringstream() << scene.rates.haptic_hz).str() + " Hz)");
    so.tissue_ticks_per_step = static_cast<std::uint32_t>(n);
    so.adaptive_tissue_rate = false;
  }
  if (options.tissue_threads != "auto") {
    unsigned long n = 0;
    std::size_t used = 0;
    try {
      n = std::stoul(options.tissue_threads, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (used == 0 || used != options.tissue_threads.size() || n < 1 ||
        n > runtime::kMaxTissueThreads)
      throw std::invalid_argument("--tissue-threads " + options.tissue_threads +
                                  ": give `auto` or a number from 1 to " +
                                  std::to_string(runtime::kMaxTissueThreads));
    so.tissue_threads = static_cast<std::uint32_t>(n);
  }
  if (options.haptic_spin != "auto") {
    const double us = number_in(options.haptic_spin).value_or(-1.0);
    if (!(us >= 0.0 && us <= 1000.0))
      throw std::invalid_argument("--haptic-spin " + options.haptic_spin +
                                  ": give `auto` or microseconds from 0 to 1000");
    so.spin_us = us;
    so.adaptive_spin = false;
  }
  for (const std::string& f : options.inject)
    so.inject.push_back(runtime::parse_fault(f));
  if (options.cpu) so.render_device = render::DevicePreference::Cpu;
  so.occlusion_culling = options.occlusion;
  ProgressLine line;
  so.progress = [&line](const runtime::SessionProgress& p) {
    if (!p.warning.empty()) {
      line.clear();
      std::cerr << "bisturi: warning: " << p.warning << "\n";
    }
    if (p.stage != "run") {
      line.show(p.stage == "build" ? "building the scene" : p.stage, 0, 1);
      return;
    }
    char text[160];
    std::snprintf(text, sizeof text,
                  "session %.1f/%.1f s  haptic %llu ticks  %llu frames  %llu overruns  %zu events  "
                  "force %.2f N",
                  p.elapsed_s, p.duration_s, static_cast<unsigned long long>(p.ticks),
                  static_cast<unsigned long long>(p.frames),
                  static_cast<unsigned long long>(p.overruns), p.events, p.force_N);
    line.show(text, static_cast<std::size_t>(p.elapsed_s * 1000.0),
              static_cast<std::size_t>(p.duration_s * 1000.0));
  };
  // Ctrl-C and SIGTERM end the session cleanly: forces zeroed first, the trace sealed, the
  // report written (ending "interrupted"). The default handlers come back afterwards.
  static std::atomic<bool> stop_requested{false};
  stop_requested.store(false);
  so.stop_requested = &stop_requested;
  struct sigaction action {};
  action.sa_handler = [](int) { stop_requested.store(true); };
  sigemptyset(&action.sa_mask);
  struct sigaction old_int {
  }, old_term{};
  sigaction(SIGINT, &action, &old_int);
  sigaction(SIGTERM, &action, &old_term);
  runtime::SessionReport r;
  try {
    r = runtime::run_session(scene, so);
  } catch (const std::exception& e) {
    sigaction(SIGINT, &old_int, nullptr);
    sigaction(SIGTERM, &old_term, nullptr);
    write_setup_failure(out, scene.name, e.what());
    throw;
  } catch (...) {
    sigaction(SIGINT, &old_int, nullptr);
    sigaction(SIGTERM, &old_term, nullptr);
    write_setup_failure(out, scene.name, "an unknown error");
    throw;
  }
  sigaction(SIGINT, &old_int, nullptr);
  sigaction(SIGTERM, &old_term, nullptr);
  line.clear();
  const runtime::MissedAroundCut around = runtime::missed_around_first_cut(r);

  // Plots.
  const auto hist = [&](const char* file, const char* title, const runtime::TimingRecorder& t) {
    if (t.samples().empty()) return;
    runtime::write_histogram_png(out / file, title, t.unit(), t.samples());
  };
  hist("haptic_period.png", "Haptic period", r.haptic_period_ms);
  hist("step_time.png", "Simulation step (instruments + soft tissue)", r.step_ms);
  hist("frame_time.png", "Frame time", r.frame_ms);
  hist("motion_to_photon.png", "Motion-to-photon latency", r.motion_to_photon_ms);
  if (!r.force.empty()) {
    std::vector<double> t, proxy, command, output;
    for (const runtime::ForceSample& f : r.force) {
      t.push_back(f.t_s);
      proxy.push_back(f.proxy_N);
      command.push_back(f.command_N);
      output.push_back(f.output_N);
    }
    const std::vector<runtime::Series> series = {
        {"proxy force on the tip", proxy, 0.1, 0.3, 0.8},
        {"thumb actuator command", command, 0.85, 0.45, 0.1},
        {"thumb actuator after the force guard", output, 0.1, 0.6, 0.2}};
    runtime::write_series_png(out / "force.png", "Force over time", "time (s)", "force (N)", t,
                              series, r.max_force_N);
  }

  nlohmann::json divergences = nlohmann::json::array();
  for (const runtime::DivergenceReport& d : r.divergences)
    divergences.push_back({{"time_s", d.time_s},
                           {"tick", d.tick},
                           {"body", d.body},
                           {"kind", d.frozen ? "frozen" : "rolled-back"},
                           {"substeps", d.substeps},
                           {"reason", d.reason}});
  nlohmann::json events = nlohmann::json::array();
  for (const runtime::EventReport& e : r.events)
    events.push_back({{"kind", runtime::to_string(e.event.kind)},
                      {"time_s", e.time_s},
                      {"tick", e.event.tick},
                      {"body", e.event.body},
                      {"hand", e.event.hand < r.hands.size() ? nlohmann::json(r.hands[e.event.hand])
                                                             : nlohmann::json(nullptr)},
                      {"detail", e.event.detail},
                      {"response_ms", e.response_ms < 0 ? nlohmann::json(nullptr)
                                                        : nlohmann::json(e.response_ms)}});
  nlohmann::json pulsing = nlohmann::json::array();
  for (const runtime::PulseReport& p : r.pulsing)
    pulsing.push_back({{"solid", p.solid},
                       {"diastolic_mmHg", p.diastolic_mmHg},
                       {"systolic_mmHg", p.systolic_mmHg}});
  nlohmann::json breathing = nlohmann::json::array();
  for (const auto& [solid, mm] : r.breathing)
    breathing.push_back({{"solid", solid}, {"breathing_mm", mm}});
  nlohmann::json solids = nlohmann::json::array();
  for (const runtime::SolidReport& s : r.solids) {
    nlohmann::json solid = {{"name", s.name},
                            {"vertices", s.vertices},
                            {"faces", s.faces},
                            {"build_ms", s.build_ms},
                            {"model", s.model}};
    if (s.model == "volume") {
      solid["volume_cells"] = s.volume_cells;
      solid["volume_nodes"] = s.volume_nodes;
      solid["volume_build_ms"] = s.volume_build_ms;
      solid["volume_refocuses"] = s.volume_refocuses;
      solid["volume_longest_refocus_ms"] = s.volume_longest_refocus_ms;
      solid["volume_separated_faces"] = s.volume_separated_faces;
      solid["volume_asleep_share"] = s.volume_asleep_share;
    }
    if (s.drawn_vertices > 0) {
      solid["drawn"] = {{"vertices", s.drawn_vertices},       {"faces", s.drawn_faces},
                        {"build_ms", s.drawn_build_ms},       {"rest_gap_mm", s.drawn_rest_gap_mm},
                        {"most_gap_mm", s.drawn_most_gap_mm}, {"cuts", s.drawn_cuts},
                        {"cuts_missed", s.drawn_cuts_missed}};
    }
    solids.push_back(std::move(solid));
  }
  const auto culling = [](const runtime::SessionReport::Culling& w) {
    return nlohmann::json{{"frames", w.frames},
                          {"draw_calls", w.draw_calls},
                          {"triangles_submitted", w.triangles_submitted},
                          {"culled",
                           {{"frustum", w.culled_frustum},
                            {"occlusion", w.culled_occlusion},
                            {"portal", w.culled_portal}}},
                          {"render_ms", summary_json(w.render_ms)}};
  };
  nlohmann::json inner = nlohmann::json::array();
  for (const runtime::SessionReport::Inner& in : r.inner)
    inner.push_back(
        {{"name", in.name}, {"solid", in.solid}, {"vertices", in.vertices}, {"faces", in.faces}});
  nlohmann::json injected = nlohmann::json::array();
  for (const runtime::FaultOutcome& f : r.injected)
    injected.push_back(
        {{"fault", runtime::to_string(f.fault.kind)},
         {"at_s", f.fault.at_s},
         {"injected_s", f.injected_s < 0 ? nlohmann::json(nullptr) : nlohmann::json(f.injected_s)},
         {"force_before_N", f.force_before_N},
         {"zero_after_ms",
          f.zero_after_ms < 0 ? nlohmann::json(nullptr) : nlohmann::json(f.zero_after_ms)}});
  const double nominal_ms = 1000.0 / r.haptic_hz;
  const nlohmann::json report = {
      {"scene", r.scene},
      {"duration_s", r.duration_s},
      {"haptic_hz", r.haptic_hz},
      {"display_hz", r.display_hz},
      {"eye_width", r.eye_width},
      {"eye_height", r.eye_height},
      {"render_device", r.render_device},
      {"render_device_is_cpu", r.render_device_is_cpu},
      {"sink", r.sink},
      {"sink_note", r.sink_note},
      {"realtime_priority", r.realtime_priority},
      {"tissue_step_in_haptic_thread", r.tissue_in_haptic_thread},
      {"tissue_lag_ticks", r.tissue_lag_ticks},
      {"tissue_rate",
       {{"adaptive", r.adaptive_tissue_rate},
        {"initial_hz", r.haptic_hz / r.first_tissue_ticks_per_step},
        {"calibration_step_ms", r.calibration_step_ms},
        {"calibration_error", r.calibration_error.empty() ? nlohmann::json(nullptr)
                                                          : nlohmann::json(r.calibration_error)},
        {"final_hz", r.haptic_hz / r.tissue_ticks_per_step},
        {"lowest_hz", r.haptic_hz / r.max_tissue_ticks_per_step},
        {"changes", r.tissue_rate_changes}}},
      {"tissue_threads", r.tissue_threads},
      {"devices", r.devices},
      {"hands", r.hands},
      {"solids", solids},
      {"bleeding",
       {{"emitted", r.bleeding.emitted},
        {"in_flight", r.bleeding.in_flight},
        {"pooled", r.bleeding.pooled},
        {"drained", r.bleeding.drained},
        {"recycled", r.bleeding.recycled},
        {"volume_ml", r.bleeding.volume_ml},
        {"most_particles", r.bleeding.most_particles},
        {"step_ms", summary_json(r.blood_step_ms)},
        {"thread",
         {{"most_behind_steps", r.bleeding.most_behind_steps},
          {"tissue_waits", r.bleeding.tissue_waits},
          {"tissue_waited_ms", r.bleeding.tissue_waited_ms},
          {"hold_at_steps", r.bleeding.hold_at_steps},
          {"holds", r.bleeding.holds},
          {"held_s", r.bleeding.held_s},
          {"threads", r.bleeding.threads}}}}},
      {"physiology",
       {{"heart_rate_bpm", r.heart_rate_bpm},
        {"pulsing", pulsing},
        {"breathing_period_s", r.breathing_period_s},
        {"breathing", breathing}}},
      {"inner", inner},
      {"field_shading_ms", r.field_shading_ms},
      {"culling", {{"before_cut", culling(r.before_cut)}, {"after_cut", culling(r.after_cut)}}},
      {"ticks", r.ticks},
      {"frames", r.frames},
      {"images", r.images},
      {"render_fps", r.render_fps},
      {"timings",
       {{"haptic_period_ms", summary_json(r.haptic_period_ms)},
        {"haptic_period_error_ms", summary_json(r.haptic_period_error_ms)},
        {"haptic_tick_ms", summary_json(r.tick_ms)},
        {"step_ms", summary_json(r.step_ms)},
        {"cut_step_ms", summary_json(r.cut_step_ms)},
        {"frame_ms", summary_json(r.frame_ms)},
        {"render_ms", summary_json(r.render_ms)},
        {"motion_to_photon_ms", summary_json(r.motion_to_photon_ms)},
        {"action_to_response_ms", summary_json(r.action_to_response_ms)},
        {"haptic_wake_late_us", summary_json(r.haptic_wake_late_us)},
        {"haptic_spin_us", summary_json(r.haptic_spin_us)}}},
      {"max_force_N", r.max_force_N},
      {"haptic_write_bounded", r.haptic_write_bounded},
      {"haptic_nominal_period_ms", nominal_ms},
      {"counts",
       {{"overruns", r.overruns},
        {"missed_deadlines", r.missed_deadlines},
        {"missed_by_late_wakeup", r.missed_by_late_wakeup},
        {"missed_before_cut", around.before},
        {"missed_after_cut", around.after},
        {"ticks_before_cut", around.ticks_before},
        {"ticks_after_cut", around.ticks_after},
        {"skipped_ticks", r.skipped_ticks},
        {"late_ticks", r.late_ticks},
        {"max_tissue_backlog", r.max_tissue_backlog},
        {"clamped_forces", r.clamped_forces},
        {"rate_limited_forces", r.rate_limited_forces},
        {"guard_latches", r.guard_latches},
        {"dropped_frames", r.dropped_frames},
        {"malformed_reports", r.malformed_reports},
        {"divergence_events", r.divergence_events},
        {"dropped_tissue_steps", r.dropped_tissue_steps},
        {"supervisor_zeros", r.supervisor_zeros},
        {"stale_ticks", r.stale_ticks},
        {"longest_stale_run", r.longest_stale_run},
        {"stale_margin_ticks", r.stale_margin_ticks},
        {"slewed_ticks", r.slewed_ticks},
        {"events", r.events.size()}}},
      {"ending", r.ending},
      {"warnings", r.warnings},
      {"error", r.error.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.error)},
      {"inputs",
       {{"haptic_silent_s", r.haptic_silent_s},
        {"haptic_longest_silence_s", r.haptic_longest_silence_s},
        {"guard_latched_s", r.guard_latched_s},
        {"haptic_untracked_s", r.haptic_untracked_s},
        {"instrument_outside_scene_s", r.instrument_outside_scene_s},
        {"haptic_clutched_s", r.haptic_clutched_s},
        {"haptic_longest_untracked_s", r.haptic_longest_untracked_s}}},
      {"faults",
       {{"haptic_device_lost_s", r.haptic_device_lost_s < 0
                                     ? nlohmann::json(nullptr)
                                     : nlohmann::json(r.haptic_device_lost_s)},
        {"haptic_device_lost_reason", r.haptic_device_lost_reason},
        {"head_tracker_lost_s", r.head_tracker_lost_s < 0 ? nlohmann::json(nullptr)
                                                          : nlohmann::json(r.head_tracker_lost_s)},
        {"head_tracker_lost_reason", r.head_tracker_lost_reason},
        {"recording_error",
         r.recording_error.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.recording_error)},
        {"injected", injected}}},
      {"events", events},
      {"divergences", divergences},
      {"final_state_hash", hex(r.final_state_hash)},
      {"trace", r.trace.empty() ? nlohmann::json(nullptr) : nlohmann::json(r.trace.string())},
      {"headset", nlohmann::json::parse(runtime::to_json(r.headset))},
      {"out", out.string()}};
  std::ofstream(out / "report.json") << report.dump(2) << "\n";

  if (options.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    const auto p = r.haptic_period_error_ms.summary();
    const auto mtp = r.motion_to_photon_ms.summary();
    const auto atr = r.action_to_response_ms.summary();
    std::ostringstream cut_note;
    if (const auto cuts = r.cut_step_ms.summary(); cuts.count > 0)
      cut_note << " (the longest cut's " << cuts.max << " ms)";
    std::cout << "session '" << r.scene << "': " << r.duration_s << " s, " << r.ticks
              << " haptic ticks, " << r.frames << " frames (" << r.render_fps << " frames/s, 2 x "
              << r.eye_width << " x " << r.eye_height << " on " << r.render_device << ")\n"
              << "  haptic period error p99 " << p.p99 << " ms, max " << p.max << " ms; "
              << r.missed_deadlines << " missed deadlines (" << r.missed_by_late_wakeup
              << " woken late, spinning " << r.haptic_spin_us.summary().p50
              << " us before a tick at the median; " << around.before << " in "
              << around.ticks_before << " ticks before the first cut, " << around.after << " in "
              << around.ticks_after << " from it), " << r.overruns << " overruns; step p99 "
              << r.step_ms.summary().p99 << " ms" << cut_note.str() << ", " << r.late_ticks
              << " late ticks; tissue at " << r.haptic_hz / r.tissue_ticks_per_step << " Hz ("
              << (r.adaptive_tissue_rate ? "adaptive, " : "fixed, ") << r.tissue_rate_changes
              << " changes)\n"
              << "  motion-to-photon p50 " << mtp.p50 << " ms, p99 " << mtp.p99
              << " ms; action-to-response p50 " << atr.p50 << " ms, max " << atr.max << " ms ("
              << atr.count << " events)\n"
              << "  " << r.clamped_forces << " clamped forces, " << r.stale_ticks
              << " ticks on a stale step (faded), " << r.dropped_frames << " dropped frames; sink "
              << r.sink << (r.sink_note.empty() ? "" : " (" + r.sink_note + ")") << "\n"
              << "  report, plots and frames in " << out.string() << "\n";
    if (r.haptic_silent_s > 0.0)
      std::cout << "  the haptic device sent nothing for " << r.haptic_silent_s
                << " s in all (longest " << r.haptic_longest_silence_s
                << " s); its forces were zero meanwhile\n";
    for (const std::string& w : r.warnings)
      std::cout << "  warning: " << w << "\n";
    if (r.haptic_untracked_s > 0.0)
      std::cout << "  the haptic device was not tracked for " << r.haptic_untracked_s
                << " s in all (longest " << r.haptic_longest_untracked_s
                << " s); its forces were zero meanwhile\n";
    if (r.haptic_device_lost_s >= 0)
      std::cout << "  haptic device lost at " << r.haptic_device_lost_s
                << " s (its force zero, the instrument held): " << r.haptic_device_lost_reason
                << "\n";
    if (r.head_tracker_lost_s >= 0)
      std::cout << "  head tracker lost at " << r.head_tracker_lost_s
                << " s (the view held its last pose): " << r.head_tracker_lost_reason << "\n";
    if (!r.recording_error.empty())
      std::cout << "  recording stopped: " << r.recording_error << "\n";
    for (const runtime::FaultOutcome& f : r.injected) {
      std::cout << "  injected " << runtime::to_string(f.fault.kind) << " at " << f.fault.at_s
                << " s: ";
      if (f.injected_s < 0)
        std::cout << "not made (the session ended first, or the device is hardware)\n";
      else if (f.zero_after_ms < 0)
        std::cout << "the force was never zero after it (" << f.force_before_N << " N before)\n";
      else
        std::cout << "zero force on every channel " << f.zero_after_ms << " ms after it ("
                  << f.force_before_N << " N before)\n";
    }
    if (r.ending == "interrupted") std::cout << "  interrupted: ended early, cleanly\n";
  }
  if (r.ending == "error") {
    std::cerr << "bisturi run: the session ended on an error: " << r.error
              << " (report.json written)\n";
    return 1;
  }
  return 0;
}

int run_replay(const ReplayOptions& options) {
  runtime::SessionReplayResult r;
  std::string error;
  try {
    r = runtime::replay_session(options.trace);
  } catch (const devices::TraceError& e) {
    error = e.what();
  }
  nlohmann::json mismatch = nullptr;
  if (r.first_mismatch)
    mismatch = {{"tick", r.first_mismatch->tick},
                {"time_ns", r.first_mismatch->time_ns},
                {"expected_N", r.first_mismatch->expected_N},
                {"actual_N", r.first_mismatch->actual_N}};
  std::string trace_error = !error.empty()          ? error
                            : r.trace_error         ? std::string(r.trace_error->what())
                            : r.devices.trace_error ? std::string(r.devices.trace_error->what())
                                                    : std::string();
  const bool passed = error.empty() && r.passed();
  const nlohmann::json j = {
      {"trace", options.trace},
      {"scene", r.scene},
      {"tissue_threads", r.tissue_threads},
      {"ticks", r.ticks},
      {"force_commands", r.force_commands},
      {"force_mismatches", r.force_mismatches},
      {"first_force_mismatch", mismatch},
      {"state_hash", hex(r.state_hash)},
      {"expected_state_hash", r.expected_state_hash ? nlohmann::json(hex(*r.expected_state_hash))
                                                    : nlohmann::json(nullptr)},
      {"device_output_mismatches", r.devices.mismatches},
      {"trace_error", trace_error.empty() ? nlohmann::json(nullptr) : nlohmann::json(trace_error)},
      {"seconds", r.seconds},
      {"passed", passed}};
  if (options.json) {
    std::cout << j.dump(2) << "\n";
  } else if (passed) {
    std::cout << options.trace << ": replay matches: " << r.force_commands
              << " force commands and the final state " << hex(r.state_hash) << " (" << r.ticks
              << " ticks, " << r.seconds << " s)\n";
  } else {
    std::cout << options.trace << ": replay does NOT match\n";
    if (!trace_error.empty()) std::cout << "  " << trace_error << "\n";
    if (r.force_mismatches > 0)
      std::cout << "  " << r.force_mismatches << " force commands differ, the first at tick "
                << r.first_mismatch->tick << "\n";
    if (!r.expected_state_hash)
      std::cout << "  the trace holds no final state (the session did not end)\n";
    else if (*r.expected_state_hash != r.state_hash)
      std::cout << "  final state " << hex(r.state_hash) << ", recorded "
                << hex(*r.expected_state_hash) << "\n";
    if (r.devices.mismatches > 0)
      std::cout << "  " << r.devices.mismatches << " device output reports differ\n";
  }
  return passed ? 0 : 2;
}

}  // namespace bisturi::cli
