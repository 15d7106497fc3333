#pragma once
// `bisturi run [SCENE] [--duration S] [--record TRACE] [--out DIR] [--eye-width W --eye-height H]
// [--json]`: runs a headset session (the default scene without SCENE) and writes its frames, a
// report (report.json) and plots (timing histograms, force over time) into DIR.
// `bisturi replay TRACE [--json]`: reruns a recorded session in virtual time and checks that the
// forces and the final state match the recording (exit status 2 when they do not).

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct RunOptions {
  std::string scene;
  std::optional<double> duration_s;
  std::string record;
  std::string out = "session";
  std::optional<std::uint32_t> eye_width;
  std::optional<std::uint32_t> eye_height;
  std::uint32_t image_every = 10;
  bool no_openxr = false;
  bool tissue_in_haptic_thread = false;
  std::uint32_t tissue_lag_ticks = 3;
  std::string tissue_hz = "auto";
  double tissue_max_load = 0.75;
  std::uint32_t blood_hold_at = 4;
  std::string tissue_threads = "auto";
  std::string haptic_spin = "auto";
  bool cpu = false;
  bool occlusion = false;
  bool print_default_scene = false;
  bool json = false;
  std::vector<std::string> inject;  ///< FAULT@SECONDS
};

struct ReplayOptions {
  std::string trace;
  bool json = false;
};

void add_run_command(CLI::App& app, RunOptions& options, int (*&run)(const RunOptions&));
void add_replay_command(CLI::App& app, ReplayOptions& options, int (*&run)(const ReplayOptions&));

int run_run(const RunOptions& options);
int run_replay(const ReplayOptions& options);

}  // namespace bisturi::cli
