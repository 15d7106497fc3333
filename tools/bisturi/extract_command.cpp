#include "extract_command.h"

#include <CLI/CLI.hpp>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/volume/label_surface.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume_io.h"
#include "progress_line.h"
#include "stopwatch.h"

namespace bisturi::cli {

namespace {

struct StageTimes {
  double read_ms = 0, surface_ms = 0, build_ms = 0, decimate_ms = 0, smooth_ms = 0, write_ms = 0;
};

}  // namespace

void add_extract_command(CLI::App& app, ExtractOptions& options,
                         int (*&run)(const ExtractOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "extract",
      "extract a surface from a volume (NRRD, NIfTI, DICOM folder) into a solid and write it");
  cmd->add_option("VOLUME", options.input, "volume file, or a folder of DICOM slices")
      ->required()
      ->check(CLI::ExistingPath);
  auto* iso = cmd->add_option("--iso", options.iso,
                              "surface where the value crosses VALUE (inside: value > VALUE)");
  auto* label = cmd->add_option("--label", options.label,
                                "surface of the voxels whose value is N (a label map)");
  iso->excludes(label);
  label->excludes(iso);
  cmd->add_option("--decimate", options.decimate,
                  "keep this fraction of the faces (quadric error decimation, topology kept)")
      ->check(CLI::Range(1e-6, 1.0));
  cmd->add_option("--smooth", options.smooth, "Taubin smoothing iterations (no shrinkage)")
      ->check(CLI::Range(0, 10000));
  cmd->add_option("--out", options.output, "output mesh (.obj or .ply), world millimetres (LPS)")
      ->required();
  cmd->add_flag("--json", options.json, "write the summary as one JSON object on stdout");
  cmd->callback([&run, &options] {
    if (!options.iso && !options.label)
      throw CLI::ValidationError("one of --iso or --label is required");
    run = run_extract;
  });
}

int run_extract(const ExtractOptions& options) {
  // Refuse a bad output name before the long work, not after it.
  const std::filesystem::path out_path(options.output);
  const MeshFormat out_format = format_from_path(out_path);
  if (out_format != MeshFormat::Obj && out_format != MeshFormat::Ply) {
    throw InputError(options.output + ": meshes are written as .obj or .ply");
  }

  ProgressLine line;
  StageTimes times;

  auto t = Clock::now();
  VolumeReadOptions read_options;
  read_options.progress = [&](std::size_t done, std::size_t total) {
    line.show("read", done, total);
  };
  const Volume volume = read_volume(options.input, read_options);
  times.read_ms = milliseconds_since(t);
  line.done("read " + options.input, times.read_ms);

  IsoSurfaceOptions iso_options;
  iso_options.progress = [&](std::size_t done, std::size_t total) {
    line.show("surface", done, total);
  };
  iso_options.build_progress = [&](std::size_t done, std::size_t total) {
    line.show("solid (DLFL)", done, total);
  };
  ExtractionStats stats;
  Dlfl mesh;
  t = Clock::now();
  if (options.label) {
    const auto wanted = static_cast<float>(*options.label);
    if (label_voxel_count(volume, wanted) == 0) {
      throw InputError(options.input + ": label " + std::to_string(*options.label) +
                       " is not in the volume");
    }
    // Smooth, not terraced: constrained windowed-sinc smoothing (label_surface.h).
    LabelSurfaceOptions label_options;
    label_options.progress = iso_options.progress;
    label_options.build_progress = iso_options.build_progress;
    label_options.smooth_progress = [&](std::size_t done, std::size_t total) {
      line.show("label surface smoothing", done, total);
    };
    LabelSurfaceStats label_stats;
    iso_options.iso = 0.5f;
    mesh = extract_label_surface(volume, wanted, label_options, &label_stats);
    stats = label_stats.extraction;
    stats.extract_seconds += label_stats.indicator_seconds + label_stats.smooth_seconds;
  } else {
    if (!std::isfinite(*options.iso)) throw InputError("--iso: the value must be finite");
    iso_options.iso = static_cast<float>(*options.iso);
    mesh = extract_isosurface(volume, iso_options, &stats);
  }
  times.surface_ms = (stats.octree_seconds + stats.extract_seconds) * 1e3;
  times.build_ms = stats.build_seconds * 1e3;
  line.done("surface and solid", milliseconds_since(t));
  const std::size_t extracted_faces = lod::polygon_face_count(mesh);

  lod::DecimateStats decimated;
  if (options.decimate < 1.0) {
    lod::DecimateOptions d;
    d.target_faces = std::max<std::size_t>(
        4, static_cast<std::size_t>(
               std::llround(options.decimate * static_cast<double>(extracted_faces))));
    d.progress = [&](std::size_t done, std::size_t total) { line.show("decimate", done, total); };
    t = Clock::now();
    decimated = lod::decimate(mesh, d);
    mesh.compact();
    times.decimate_ms = milliseconds_since(t);
    line.done("decimate", times.decimate_ms);
  }
  if (options.smooth > 0) {
    lod::SmoothOptions s;
    s.iterations = static_cast<std::size_t>(options.smooth);
    s.progress = [&](std::size_t done, std::size_t total) { line.show("smooth", done, total); };
    t = Clock::now();
    lod::smooth_taubin(mesh, s);
    times.smooth_ms = milliseconds_since(t);
    line.done("smooth", times.smooth_ms);
  }

  t = Clock::now();
  const ExportedPolygons exported = export_polygons(mesh);
  if (out_format == MeshFormat::Obj) {
    write_obj(out_path, exported.polygons);
  } else {
    write_ply(out_path, exported.polygons);
  }
  times.write_ms = milliseconds_since(t);
  line.clear();

  const ValidationReport validation = validate(mesh);
  const MeshStatistics statistics = mesh_statistics(mesh);
  nlohmann::json parts = nlohmann::json::array();
  for (const PartTopology& p : statistics.parts) {
    parts.push_back({{"faces", p.faces},
                     {"vertices", p.vertices},
                     {"edges", p.edges},
                     {"closed", p.rings == 0},
                     {"boundary_loops", p.rings},
                     {"euler", p.euler_characteristic},
                     {"genus", p.genus}});
  }
  const nlohmann::json summary = {
      {"file", options.input},
      {"out", options.output},
      {"dims", volume.geometry.dims},
      {"voxels", volume.geometry.voxel_count()},
      {"iso", iso_options.iso},
      {"label", options.label ? nlohmann::json(*options.label) : nlohmann::json(nullptr)},
      {"extracted_faces", extracted_faces},
      {"faces", exported.polygons.face_count()},
      {"vertices", exported.polygons.positions.size()},
      {"parts", parts},
      {"decimation",
       {{"collapses", decimated.collapses},
        {"rejected_topology", decimated.rejected_topology},
        {"rejected_geometry", decimated.rejected_geometry},
        {"max_error_mm", decimated.max_error}}},
      {"cells_visited", stats.cells_visited},
      {"leaves_skipped", stats.leaves_skipped},
      {"dlfl_valid", validation.ok()},
      {"times_ms",
       {{"read", times.read_ms},
        {"surface", times.surface_ms},
        {"solid", times.build_ms},
        {"decimate", times.decimate_ms},
        {"smooth", times.smooth_ms},
        {"write", times.write_ms}}}};
  if (options.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << options.input << " -> " << options.output << "\n"
              << "  " << exported.polygons.face_count() << " faces, "
              << exported.polygons.positions.size() << " vertices, " << statistics.parts.size()
              << " parts (extracted " << extracted_faces << " faces)\n";
    std::size_t shown = 0;
    for (const PartTopology& p : statistics.parts) {
      if (++shown > 20) {
        std::cout << "  ... " << statistics.parts.size() - 20 << " more parts\n";
        break;
      }
      std::cout << "  part: " << p.faces << " faces, "
                << (p.rings == 0 ? "closed" : std::to_string(p.rings) + " boundary loops")
                << ", genus " << p.genus << "\n";
    }
    std::cout << "  times (ms): read " << times.read_ms << ", surface " << times.surface_ms
              << ", solid " << times.build_ms << ", decimate " << times.decimate_ms << ", smooth "
              << times.smooth_ms << ", write " << times.write_ms << "\n";
  }
  if (!validation.ok()) {
    std::cerr << "bisturi: internal error: the extracted solid does not validate\n";
    return 3;
  }
  return 0;
}

}  // namespace bisturi::cli
