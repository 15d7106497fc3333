#pragma once
// `bisturi pipeline SCAN --plan PLAN.toml --out DIR [--case NAME] [--force] [--json]`: one scan,
// unattended, stateless. Reads the scan, segments the vessel the plan names, extracts its surface,
// traces its centreline, measures its sections, makes the session solid, and writes into DIR
// (and nowhere else) result.json, surface.ply (the measured surface), vessel.obj (the session
// solid), scene_solid.toml (a [[solids]] entry naming it), centreline.csv and profile.png (the
// diameter along the vessel). Every file is written under a temporary name and renamed;
// result.json last. A rerun whose scan, plan and tool version have the checksums of an ok
// result.json does no work. A failed case writes a result.json with status "failed" and the
// stage and error, and exits 1; while a case runs, its result.json says "running".

#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct PipelineOptions {
  std::string scan;
  std::string plan;
  std::string out;
  std::string case_name;  ///< empty: the scan's file name without its extensions
  bool force = false;
  bool json = false;
};

void add_pipeline_command(CLI::App& app, PipelineOptions& options,
                          int (*&run)(const PipelineOptions&));

int run_pipeline(const PipelineOptions& options);

}  // namespace bisturi::cli
