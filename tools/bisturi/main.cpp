// bisturi: the command-line program. Sub-commands parse their options here and call the
// libraries; libraries never print.

#include <CLI/CLI.hpp>
#include <exception>
#include <iostream>

#include "bisturi/runtime/heap_policy.h"
#include "bisturi/runtime/version.h"
#include "cohort_command.h"
#include "device_command.h"
#include "extract_command.h"
#include "measure_command.h"
#include "mesh_command.h"
#include "mesh_demo.h"
#include "pipeline_command.h"
#include "render_command.h"
#include "run_command.h"
#include "segment_command.h"
#include "tissue_command.h"
#include "trace_command.h"
#include "volume_command.h"

namespace {

int run(int argc, char** argv) {
  CLI::App app{"bisturi: an immersive surgical-simulation runtime"};
  app.require_subcommand(0, 1);
  bool version = false;
  app.add_flag("--version", version, "print the version and exit");

  bisturi::cli::MeshDemoOptions demo;
  CLI::App* demo_cmd = app.add_subcommand(
      "demo", "build DLFL solids (seed figures, a large torus) and print their statistics");
  demo_cmd
      ->add_option("--torus-segments", demo.torus_segments,
                   "segments around the large torus (faces = segments^2)")
      ->check(CLI::Range(std::size_t{4}, std::size_t{4096}));
  demo_cmd->add_flag("--json", demo.json, "write the statistics as one JSON object on stdout");
  demo_cmd->add_flag("--quiet", demo.quiet, "no progress line");

  bisturi::cli::MeshOptions mesh;
  int (*run_mesh)(const bisturi::cli::MeshOptions&) = nullptr;
  bisturi::cli::add_mesh_command(app, mesh, run_mesh);

  bisturi::cli::VolumeOptions volume;
  int (*run_volume)(const bisturi::cli::VolumeOptions&) = nullptr;
  bisturi::cli::add_volume_command(app, volume, run_volume);

  bisturi::cli::SegmentOptions segment;
  int (*run_segment)(const bisturi::cli::SegmentOptions&) = nullptr;
  bisturi::cli::add_segment_command(app, segment, run_segment);

  bisturi::cli::ExtractOptions extract;
  int (*run_extract)(const bisturi::cli::ExtractOptions&) = nullptr;
  bisturi::cli::add_extract_command(app, extract, run_extract);

  bisturi::cli::MeasureCommandOptions measure;
  int (*run_measure)(const bisturi::cli::MeasureCommandOptions&) = nullptr;
  bisturi::cli::add_measure_command(app, measure, run_measure);

  bisturi::cli::TraceOptions trace;
  int (*run_trace)(const bisturi::cli::TraceOptions&) = nullptr;
  bisturi::cli::add_trace_command(app, trace, run_trace);

  bisturi::cli::DeviceOptions device;
  int (*run_device)(const bisturi::cli::DeviceOptions&) = nullptr;
  bisturi::cli::add_device_command(app, device, run_device);

  bisturi::cli::RenderOptions render;
  int (*run_render)(const bisturi::cli::RenderOptions&) = nullptr;
  bisturi::cli::add_render_command(app, render, run_render);

  bisturi::cli::RunOptions run_options;
  int (*run_run)(const bisturi::cli::RunOptions&) = nullptr;
  bisturi::cli::add_run_command(app, run_options, run_run);

  bisturi::cli::ReplayOptions replay;
  int (*run_replay)(const bisturi::cli::ReplayOptions&) = nullptr;
  bisturi::cli::add_replay_command(app, replay, run_replay);

  bisturi::cli::PipelineOptions pipeline;
  int (*run_pipeline)(const bisturi::cli::PipelineOptions&) = nullptr;
  bisturi::cli::add_pipeline_command(app, pipeline, run_pipeline);

  bisturi::cli::CohortOptions cohort;
  int (*run_cohort)(const bisturi::cli::CohortOptions&) = nullptr;
  bisturi::cli::add_cohort_command(app, cohort, run_cohort);
  bisturi::cli::TissueIndentOptions tissue;
  int (*run_tissue)(const bisturi::cli::TissueIndentOptions&) = nullptr;
  bisturi::cli::add_tissue_command(app, tissue, run_tissue);

  CLI11_PARSE(app, argc, argv);
  if (version) {
    std::cout << "bisturi " << bisturi::kVersion << " (" << bisturi::kBuildType << ")\n";
    return 0;
  }
  if (demo_cmd->parsed()) return bisturi::cli::run_mesh_demo(demo);
  if (run_mesh != nullptr) return run_mesh(mesh);
  if (run_volume != nullptr) return run_volume(volume);
  if (run_segment != nullptr) return run_segment(segment);
  if (run_extract != nullptr) return run_extract(extract);
  if (run_measure != nullptr) return run_measure(measure);
  if (run_trace != nullptr) return run_trace(trace);
  if (run_device != nullptr) return run_device(device);
  if (run_render != nullptr) return run_render(render);
  if (run_run != nullptr) return run_run(run_options);
  if (run_replay != nullptr) return run_replay(replay);
  if (run_pipeline != nullptr) return run_pipeline(pipeline);
  if (run_cohort != nullptr) return run_cohort(cohort);
  if (run_tissue != nullptr) return run_tissue(tissue);
  std::cout << app.help();
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  // Libraries report failures as exceptions that name the element and the reason; the user sees
  // that message, never a crash.
  try {
    // Before any frame: the renderer's per-frame memory stays in the process (heap_policy.h).
    (void)bisturi::runtime::keep_freed_heap();
    return run(argc, argv);
  } catch (const std::exception& e) {
    std::cerr << "bisturi: error: " << e.what() << "\n";
    return 1;
  }
}
