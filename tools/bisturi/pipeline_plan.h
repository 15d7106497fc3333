#pragma once
// The plan of `bisturi pipeline` and `bisturi cohort`: a TOML file that says what to do with
// every scan of a cohort. Checked key by key: an unknown key or a bad value is an error naming
// the file, the line and the key.
//
//   [segmentation]
//   method = "threshold"          # "threshold" (range = [lo, hi]), "window" (range = [centre,
//   range = [150.0, 2000.0]       #  width], a CT window) or "label" (label = N of a label map)
//   seed_mm = [x, y, z]           # optional, LPS world mm: the object connected to this point;
//   connectivity = 26             #  without it the largest object in the range
//   [surface]
//   smooth = 3                    # Taubin iterations of the session solid
//   decimate = 0.25               # fraction of the faces the session solid keeps
//   [centreline]
//   section_step_mm = 2.0         # a section every this many mm along the centreline
//   min_branch_mm = 0.0           # 0: prune branches shorter than 3 radii where they join
//   start_mm = [x, y, z]          # optional: the end nearest this point is the start
//   end_margin_radii = 2.5        # no section this many radii from a tip ...
//   junction_margin_radii = 2.0   # ... or from a bifurcation
//   orthogonal = true             # search the smallest section through each point
//   [cluster]                     # `bisturi cohort plan` only (not part of the plan checksum)
//   cases_per_task = 1
//   max_running = 8               # the job array's %K throttle
//   cpus_per_task = 1
//   mem_mb = 2000
//   time_limit = "00:20:00"
//   partition = ""                # empty: the cluster's default

#include <array>
#include <filesystem>
#include <optional>
#include <string>

#include <nlohmann/json.hpp>

namespace bisturi::cli {

struct PipelinePlan {
  std::string method = "threshold";
  std::array<double, 2> range{150.0, 2000.0};  ///< threshold [lo, hi] or window [centre, width]
  long long label = 1;
  std::optional<std::array<double, 3>> seed_mm;
  int connectivity = 26;

  int smooth = 3;
  double decimate = 0.25;

  double section_step_mm = 2.0;
  double min_branch_mm = 0.0;
  std::optional<std::array<double, 3>> start_mm;
  double end_margin_radii = 2.5;
  double junction_margin_radii = 2.0;
  bool orthogonal = true;

  int cases_per_task = 1;
  int max_running = 8;
  int cpus_per_task = 1;
  int mem_mb = 2000;
  std::string time_limit = "00:20:00";
  std::string partition;

  /// The threshold range [lo, hi] (the window converted).
  [[nodiscard]] std::array<double, 2> threshold_range() const;
};

/// Reads and checks a plan. Throws std::runtime_error naming the file, line and key.
PipelinePlan read_plan(const std::filesystem::path& file);

/// Everything that decides a case's result (not [cluster]); its dump is the plan's checksum text.
nlohmann::json plan_processing_json(const PipelinePlan& plan);
nlohmann::json plan_cluster_json(const PipelinePlan& plan);

}  // namespace bisturi::cli
