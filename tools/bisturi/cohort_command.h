#pragma once
// `bisturi cohort`: a whole cohort of scans through `bisturi pipeline` on a Slurm cluster.
//   cohort plan MANIFEST.csv --plan PLAN.toml --out DIR   writes DIR/cohort.sbatch, a job array
//       (one task per case or per [cluster] cases_per_task cases, %K throttle from max_running,
//       per-task logs in DIR/logs, resources from [cluster]), DIR/cases.tsv (index, task, case,
//       scan) and a copy of the plan; `sbatch DIR/cohort.sbatch` runs it.
//   cohort gather DIR   collects every DIR/cases/NAME/result.json into DIR/cohort.csv (one row
//       per section), DIR/cohort_cases.csv (one row per case) and DIR/cohort.json, and lists the
//       cases that did not finish with the sbatch command that reruns exactly their tasks.
//   cohort phantoms --out DIR   writes a small cohort of vessel phantoms (scans, manifest.csv,
//       truth.csv with the true axis and radii, plan.toml): the worked example and the tests.

#include <string>
#include <vector>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct CohortOptions {
  enum class Action { None, Plan, Gather, Phantoms } action = Action::None;
  std::string manifest;
  std::string plan;
  std::string out;
  std::string bisturi;  ///< the program the tasks run (default: this one)
  int count = 6;
  double spacing_mm = 0.8;
  double noise_hu = 0.0;
  std::vector<double> field_of_view_mm;  ///< empty: the vessel's box and a margin
  bool json = false;
};

void add_cohort_command(CLI::App& app, CohortOptions& options, int (*&run)(const CohortOptions&));

int run_cohort(const CohortOptions& options);

}  // namespace bisturi::cli
