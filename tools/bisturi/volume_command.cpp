#include "volume_command.h"

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/scene/volume/volume_io.h"
#include "progress_line.h"

namespace bisturi::cli {

namespace {

nlohmann::json number(double v) {
  return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr);
}

nlohmann::json vec(const glm::dvec3& v) {
  return nlohmann::json::array({v.x, v.y, v.z});
}

}  // namespace

void add_volume_command(CLI::App& app, VolumeOptions& options, int (*&run)(const VolumeOptions&)) {
  CLI::App* volume = app.add_subcommand("volume", "read and inspect image volumes (CT, MR)");
  volume->require_subcommand(1);
  CLI::App* info = volume->add_subcommand(
      "info",
      "report the grid, world geometry (LPS mm), value range and modality of a NRRD (.nrrd, "
      ".nhdr), NIfTI-1 (.nii, .nii.gz) file or a folder of DICOM slices");
  info->add_option("FILE", options.input, "volume file, or a folder holding one DICOM series")
      ->required()
      ->check(CLI::ExistingPath);
  info->add_option("--series", options.series_uid,
                   "DICOM: the SeriesInstanceUID to read when the folder holds several");
  info->add_flag("--json", options.json, "write the report as one JSON object on stdout");
  info->callback([&run] { run = run_volume_info; });

  CLI::App* phantom = volume->add_subcommand(
      "phantom",
      "write an analytic phantom volume: the signed distance (mm, positive inside) to a known "
      "surface, which `bisturi extract --iso 0` turns into a solid");
  std::string shapes;
  for (const std::string& name : phantom_shape_names())
    shapes += (shapes.empty() ? "" : ", ") + name;
  phantom->add_option("--shape", options.shape, "one of: " + shapes)
      ->check(CLI::IsMember(phantom_shape_names()));
  phantom->add_option("--dims", options.dims, "samples along i, j, k")->expected(3);
  phantom->add_option("--spacing", options.spacing, "millimetres between samples along i, j, k")
      ->expected(3);
  phantom->add_option("-a", options.a,
                      "first size in mm (radius, outer or major radius, gyroid period); "
                      "0 fits the volume");
  phantom->add_option("-b", options.b,
                      "second size in mm (inner or minor radius, gap between spheres); 0: default");
  phantom->add_option("--out", options.output, "volume to write (.nrrd, .nii, .nii.gz)")
      ->required();
  phantom->add_flag("--json", options.json, "write a JSON summary on stdout");
  phantom->callback([&run] { run = run_volume_phantom; });
}

int run_volume_phantom(const VolumeOptions& options) {
  PhantomOptions p;
  p.shape = phantom_shape_from_string(options.shape);
  p.dims = {options.dims[0], options.dims[1], options.dims[2]};
  p.spacing = glm::dvec3(options.spacing[0], options.spacing[1], options.spacing[2]);
  p.a = options.a;
  p.b = options.b;
  const auto t0 = std::chrono::steady_clock::now();
  const Volume volume = make_phantom(p);
  const std::string ext = std::filesystem::path(options.output).extension().string();
  if (ext == ".nrrd") {
    write_nrrd(options.output, volume, NrrdEncoding::Raw);
  } else if (ext == ".nii" || ext == ".gz") {
    write_nifti(options.output, volume);
  } else {
    throw InputError(options.output + ": volumes are written as .nrrd, .nii or .nii.gz");
  }
  const double ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  if (options.json) {
    const nlohmann::json j = {{"out", options.output},
                              {"shape", options.shape},
                              {"dims", volume.geometry.dims},
                              {"spacing", vec(volume.geometry.spacing)},
                              {"voxels", volume.geometry.voxel_count()},
                              {"ms", ms}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "wrote " << options.output << ": " << options.shape << " phantom, "
              << volume.geometry.dims[0] << "x" << volume.geometry.dims[1] << "x"
              << volume.geometry.dims[2] << " samples (" << ms << " ms)\n";
  }
  return 0;
}

int run_volume_info(const VolumeOptions& options) {
  const auto t0 = std::chrono::steady_clock::now();
  VolumeFile file;
  {
    ProgressLine line;
    const std::string stage = "reading " + options.input;
    VolumeReadOptions read_options;
    read_options.series_uid = options.series_uid;
    read_options.progress = [&line, &stage](std::size_t done, std::size_t total) {
      line.show(stage, done, total);
    };
    file = read_volume_file(options.input, read_options);
  }
  const double read_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
  const Volume& v = file.volume;
  const VolumeGeometry& g = v.geometry;
  const ValueRange range = value_range(v);
  if (options.json) {
    nlohmann::json direction = nlohmann::json::array();
    for (int r = 0; r < 3; ++r) {
      direction.push_back({g.direction[0][r], g.direction[1][r], g.direction[2][r]});
    }
    const nlohmann::json report = {
        {"file", options.input},
        {"format", to_string(file.format)},
        {"value_type", file.stored_type},
        {"rescaled", file.rescaled},
        {"world_frame", "LPS mm"},
        {"dims", {g.dims[0], g.dims[1], g.dims[2]}},
        {"spacing", vec(g.spacing)},
        {"origin", vec(g.origin)},
        {"direction", direction},
        {"value_min", number(range.min)},
        {"value_max", number(range.max)},
        {"finite_values", range.finite_count},
        {"voxels", g.voxel_count()},
        {"modality", v.modality.empty() ? nlohmann::json(nullptr) : nlohmann::json(v.modality)},
        {"read_ms", read_ms}};
    std::cout << report.dump(2) << "\n";
    return 0;
  }
  std::cout << options.input << " (" << to_string(file.format) << ", stored as " << file.stored_type
            << (file.rescaled ? ", rescaled" : "") << ")\n"
            << "  dimensions " << g.dims[0] << " x " << g.dims[1] << " x " << g.dims[2] << " ("
            << g.voxel_count() << " voxels)\n"
            << "  spacing    " << g.spacing.x << " x " << g.spacing.y << " x " << g.spacing.z
            << " mm\n"
            << "  origin     (" << g.origin.x << ", " << g.origin.y << ", " << g.origin.z
            << ") mm, LPS\n"
            << "  direction  (columns: +i, +j, +k in LPS)\n";
  for (int r = 0; r < 3; ++r) {
    std::cout << "    [" << g.direction[0][r] << ", " << g.direction[1][r] << ", "
              << g.direction[2][r] << "]\n";
  }
  std::cout << "  values     " << range.min << " .. " << range.max;
  if (range.finite_count != g.voxel_count()) {
    std::cout << " (" << g.voxel_count() - range.finite_count << " not finite)";
  }
  std::cout << "\n";
  if (!v.modality.empty()) std::cout << "  modality   " << v.modality << "\n";
  std::cout << "  read " << read_ms << " ms\n";
  return 0;
}

}  // namespace bisturi::cli
