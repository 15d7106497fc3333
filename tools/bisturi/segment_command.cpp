#include "segment_command.h"

#include "number_checks.h"

#include <CLI/CLI.hpp>
#include <chrono>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/segmentation.h"
#include "bisturi/scene/volume/volume_io.h"
#include "progress_line.h"
#include "stopwatch.h"

namespace bisturi::cli {

namespace {

/// The label map as a volume the readers and `extract --label` understand (float32 holds every
/// label below 2^24 exactly).
Volume labels_as_volume(const LabelVolume& labels) {
  if (labels.label_count >= (1u << 24)) {
    throw InputError("segmentation: " + std::to_string(labels.label_count) +
                     " labels do not fit a float32 label map (at most 16777215)");
  }
  Volume out;
  out.geometry = labels.geometry;
  out.values.resize(labels.values.size());
  for (std::size_t i = 0; i < labels.values.size(); ++i) {
    out.values[i] = static_cast<float>(labels.values[i]);
  }
  return out;
}

}  // namespace

void add_segment_command(CLI::App& app, SegmentOptions& options,
                         int (*&run)(const SegmentOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "segment", "segment a volume into labelled objects and write the label map (NRRD)");
  cmd->add_option("VOLUME", options.input, "volume file, or a folder of DICOM slices")
      ->required()
      ->check(CLI::ExistingPath);
  auto* thr = cmd->add_option("--threshold", options.threshold,
                              "inside: LO <= value <= HI (e.g. CT bone: 300 3000)")
                  ->expected(2);
  auto* win = cmd->add_option("--window", options.window,
                              "inside: the CT window CENTRE WIDTH, [c - w/2, c + w/2]")
                  ->expected(2);
  auto* sm = cmd->add_option("--split-merge", options.split_merge_tolerance,
                             "octree split-and-merge: regions whose values differ by at most "
                             "TOLERANCE (every voxel gets a label)");
  thr->excludes(win)->excludes(sm);
  win->excludes(sm);
  cmd->add_option("--seed", options.seed,
                  "region growing: keep only the object connected to voxel I J K")
      ->expected(3)
      ->excludes(sm);
  cmd->add_option("--connectivity", options.connectivity, "6 (faces) or 26 (faces, edges, corners)")
      ->check(CLI::IsMember({6, 26}));
  cmd->add_option("--min-voxels", options.min_voxels, "objects smaller than this become background")
      ->check(kNonNegative);
  cmd->add_option("--min-region-voxels", options.min_region_voxels,
                  "split-and-merge: smaller regions join their closest neighbour")
      ->check(kPositive);
  cmd->add_option("--out", options.output, "label map to write (.nrrd or .nii / .nii.gz)")
      ->required();
  cmd->add_flag("--json", options.json, "write the objects as one JSON object on stdout");
  cmd->callback([&run, &options] {
    if (options.threshold.empty() && options.window.empty() && !options.split_merge_tolerance) {
      throw CLI::ValidationError("one of --threshold, --window or --split-merge is required");
    }
    run = run_segment;
  });
}

int run_segment(const SegmentOptions& options) {
  ProgressLine line;
  auto t = Clock::now();
  VolumeReadOptions read_options;
  read_options.progress = [&](std::size_t done, std::size_t total) {
    line.show("read", done, total);
  };
  const Volume volume = read_volume(options.input, read_options);
  const double read_ms = milliseconds_since(t);
  line.done("read " + options.input, read_ms);

  t = Clock::now();
  const Connectivity connectivity =
      options.connectivity == 26 ? Connectivity::TwentySix : Connectivity::Six;
  LabelVolume labels;
  std::vector<ComponentStats> stats;
  std::string method;
  if (options.split_merge_tolerance) {
    method = "split-and-merge";
    SplitMergeOptions sm;
    sm.tolerance = static_cast<float>(*options.split_merge_tolerance);
    sm.min_region_voxels = options.min_region_voxels;
    labels = split_and_merge(volume, sm);
  } else {
    IntensityRange range;
    if (!options.threshold.empty()) {
      range = {static_cast<float>(options.threshold[0]), static_cast<float>(options.threshold[1])};
    } else {
      range = window_range(static_cast<float>(options.window[0]),
                           static_cast<float>(options.window[1]));
    }
    Grid<std::uint8_t> mask;
    if (!options.seed.empty()) {
      method = "region growing";
      mask = region_grow(volume, {options.seed[0], options.seed[1], options.seed[2]}, range.lo,
                         range.hi, connectivity);
    } else {
      method = "threshold and connected components";
      mask = threshold(volume, range);
    }
    Components components =
        label_components(mask, connectivity, ComponentOptions{options.min_voxels});
    labels = std::move(components.labels);
    stats = std::move(components.stats);
  }
  const double segment_ms = milliseconds_since(t);
  line.done("segment (" + method + ")", segment_ms);

  t = Clock::now();
  const Volume out = labels_as_volume(labels);
  const std::string ext = std::filesystem::path(options.output).extension().string();
  if (ext == ".nrrd") {
    write_nrrd(options.output, out, NrrdEncoding::Gzip);
  } else {
    write_nifti(options.output, out);
  }
  const double write_ms = milliseconds_since(t);

  const glm::dvec3 s = volume.geometry.spacing;
  const double voxel_mm3 = s.x * s.y * s.z;
  nlohmann::json objects = nlohmann::json::array();
  for (const ComponentStats& c : stats) {
    objects.push_back({{"label", c.label},
                       {"voxels", c.voxel_count},
                       {"volume_mm3", static_cast<double>(c.voxel_count) * voxel_mm3},
                       {"bounds_origin", c.bounds.origin},
                       {"bounds_size", c.bounds.size},
                       {"first_voxel", c.first_voxel}});
  }
  const nlohmann::json summary = {
      {"file", options.input},
      {"out", options.output},
      {"method", method},
      {"labels", labels.label_count},
      {"objects", objects},
      {"times_ms", {{"read", read_ms}, {"segment", segment_ms}, {"write", write_ms}}}};
  if (options.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << options.input << " -> " << options.output << " (" << method
              << "): " << labels.label_count << " labels\n";
    std::size_t shown = 0;
    for (const ComponentStats& c : stats) {
      if (++shown > 20) {
        std::cout << "  ... " << stats.size() - 20 << " more\n";
        break;
      }
      std::cout << "  label " << c.label << ": " << c.voxel_count << " voxels ("
                << static_cast<double>(c.voxel_count) * voxel_mm3 << " mm^3)\n";
    }
    std::cout << "  times (ms): read " << read_ms << ", segment " << segment_ms << ", write "
              << write_ms << "\n";
  }
  return 0;
}

}  // namespace bisturi::cli
