#include "mesh_command.h"

#include "number_checks.h"

#include <CLI/CLI.hpp>
#include <chrono>
#include <cstdio>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>

#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"
#include "progress_line.h"

namespace bisturi::cli {

namespace {

struct Loaded {
  MeshFile file;
  ImportResult imported;
  double read_ms = 0.0;
  double build_ms = 0.0;
};

Loaded load(const MeshOptions& options) {
  ProgressLine line;
  Loaded out;
  const auto t0 = std::chrono::steady_clock::now();
  ReadOptions read_options;
  read_options.progress = [&](std::size_t done, std::size_t total) {
    line.show("reading " + options.input, done, total);
  };
  out.file = read_mesh(options.input, read_options);
  line.clear();
  for (const std::string& w : out.file.warnings)
    std::cerr << "bisturi: warning: " << w << "\n";
  const auto t1 = std::chrono::steady_clock::now();
  ImportOptions import_options;
  import_options.weld = options.weld;
  import_options.weld_tolerance = options.weld_tolerance;
  import_options.progress = [&](std::string_view stage, std::size_t done, std::size_t total) {
    line.show(stage, done, total);
  };
  out.imported = import_polygons(out.file.polygons, out.file.has_vertex_list, import_options);
  const auto t2 = std::chrono::steady_clock::now();
  out.read_ms = std::chrono::duration<double, std::milli>(t1 - t0).count();
  out.build_ms = std::chrono::duration<double, std::milli>(t2 - t1).count();
  return out;
}

const char* format_name(MeshFormat f) {
  switch (f) {
    case MeshFormat::Obj:
      return "obj";
    case MeshFormat::Ply:
      return "ply";
    case MeshFormat::Stl:
      return "stl";
    case MeshFormat::Off:
      return "off";
  }
  return "unknown";
}

nlohmann::json info_json(const MeshOptions& options, const Loaded& loaded, bool valid) {
  const ImportReport& r = loaded.imported.report;
  nlohmann::json parts = nlohmann::json::array();
  for (const ImportPart& p : r.parts) {
    parts.push_back({{"faces", p.faces},
                     {"vertices", p.vertices},
                     {"edges", p.edges},
                     {"closed", p.closed},
                     {"boundary_loops", p.boundary_loops},
                     {"orientable", p.orientable},
                     {"euler", p.euler},
                     {"genus", p.genus ? nlohmann::json(*p.genus) : nlohmann::json(nullptr)}});
  }
  std::map<std::string, std::size_t> reasons;
  nlohmann::json dropped = nlohmann::json::array();
  for (const DroppedFace& d : r.dropped) {
    ++reasons[std::string(to_string(d.reason))];
    if (dropped.size() < 1000)
      dropped.push_back({{"face", d.face}, {"reason", to_string(d.reason)}});
  }
  return {{"file", options.input},
          {"format", format_name(loaded.file.format)},
          {"warnings", loaded.file.warnings},
          {"input_vertices", r.input_vertices},
          {"input_faces", r.input_faces},
          {"welded_vertices", r.welded_vertices},
          {"vertices", r.vertices},
          {"isolated_vertices", r.isolated_vertices},
          {"edges", r.edges},
          {"faces", r.faces},
          {"dropped_faces", r.dropped.size()},
          {"dropped_reasons", reasons},
          {"dropped", dropped},
          {"nonmanifold_edges", r.nonmanifold_edges},
          {"nonmanifold_vertices", r.nonmanifold_vertices},
          {"flipped_faces", r.flipped_faces},
          {"duplicate_faces", r.duplicate_faces},
          {"seam_edges", r.seam_edges},
          {"parts", parts},
          {"dlfl_valid", valid},
          {"read_ms", loaded.read_ms},
          {"build_ms", loaded.build_ms}};
}

}  // namespace

void add_mesh_command(CLI::App& app, MeshOptions& options, int (*&run)(const MeshOptions&)) {
  CLI::App* mesh = app.add_subcommand("mesh", "read, inspect and convert polygon mesh files");
  mesh->require_subcommand(1);
  auto add_weld_options = [&options](CLI::App* cmd) {
    cmd->add_flag("--weld", options.weld, "weld vertices at equal coordinates (STL always is)");
    cmd->add_option("--weld-tolerance", options.weld_tolerance,
                    "weld vertices closer than this distance, in model units")
        ->check(kNonNegative);
  };

  CLI::App* info = mesh->add_subcommand(
      "info", "build the DLFL of a mesh file (OBJ, PLY, STL, OFF) and report its topology");
  info->add_option("FILE", options.input, "mesh file")->required()->check(CLI::ExistingFile);
  info->add_flag("--json", options.json, "write the report as one JSON object on stdout");
  add_weld_options(info);
  info->callback([&run] { run = run_mesh_info; });

  CLI::App* convert = mesh->add_subcommand(
      "convert", "read a mesh file, build its DLFL and write its faces as OBJ or PLY");
  convert->add_option("IN", options.input, "input mesh file")->required()->check(CLI::ExistingFile);
  convert->add_option("OUT", options.output, "output file (.obj or .ply)")->required();
  convert->add_option("--ply-encoding", options.ply_encoding, "PLY encoding")
      ->check(CLI::IsMember({"ascii", "binary", "binary-be"}));
  convert->add_flag("--json", options.json, "write a JSON summary on stdout");
  add_weld_options(convert);
  convert->callback([&run] { run = run_mesh_convert; });
}

int run_mesh_info(const MeshOptions& options) {
  const Loaded loaded = load(options);
  const ValidationReport validation = validate(loaded.imported.mesh);
  const nlohmann::json report = info_json(options, loaded, validation.ok());
  if (options.json) {
    std::cout << report.dump(2) << "\n";
  } else {
    const ImportReport& r = loaded.imported.report;
    std::cout << options.input << " (" << format_name(loaded.file.format) << ")\n"
              << "  vertices " << r.vertices << " (+" << r.isolated_vertices << " isolated, "
              << r.welded_vertices << " welded)  edges " << r.edges << "  faces " << r.faces
              << "\n  dropped faces " << r.dropped.size() << "  flipped faces " << r.flipped_faces
              << "  duplicate faces " << r.duplicate_faces
              << "\n  non-manifold: " << r.nonmanifold_edges << " edges, " << r.nonmanifold_vertices
              << " vertices  seams " << r.seam_edges << "\n";
    for (const auto& [reason, count] : report["dropped_reasons"].items()) {
      std::cout << "    dropped for " << reason << ": " << count.get<std::size_t>() << "\n";
    }
    for (std::size_t i = 0; i < r.parts.size() && i < 20; ++i) {
      const ImportPart& p = r.parts[i];
      std::cout << "  part " << i << ": " << p.faces << " faces, " << (p.closed ? "closed" : "open")
                << ", " << p.boundary_loops << " boundary loops, "
                << (p.orientable ? "orientable" : "non-orientable") << ", euler " << p.euler;
      if (p.genus) std::cout << ", genus " << *p.genus;
      std::cout << "\n";
    }
    if (r.parts.size() > 20) std::cout << "  ... " << r.parts.size() - 20 << " more parts\n";
    std::cout << "  read " << loaded.read_ms << " ms, built " << loaded.build_ms << " ms, DLFL "
              << (validation.ok() ? "valid" : "INVALID") << "\n";
  }
  if (!validation.ok()) {
    std::cerr << "bisturi: internal error: the DLFL of " << options.input << " does not validate:\n"
              << validation.summary();
    return 2;
  }
  return 0;
}

int run_mesh_convert(const MeshOptions& options) {
  const Loaded loaded = load(options);
  const ExportedPolygons out = export_polygons(loaded.imported.mesh);
  const MeshFormat format = format_from_path(options.output);
  if (format == MeshFormat::Obj) {
    write_obj(options.output, out.polygons);
  } else if (format == MeshFormat::Ply) {
    const PlyEncoding encoding = options.ply_encoding == "ascii" ? PlyEncoding::Ascii
                                 : options.ply_encoding == "binary-be"
                                     ? PlyEncoding::BinaryBigEndian
                                     : PlyEncoding::BinaryLittleEndian;
    write_ply(options.output, out.polygons, encoding);
  } else {
    throw InputError(options.output + ": can only write .obj and .ply files");
  }
  const ImportReport& r = loaded.imported.report;
  if (options.json) {
    std::cout << nlohmann::json{{"input", options.input},
                                {"output", options.output},
                                {"vertices", out.polygons.positions.size()},
                                {"faces", out.polygons.face_count()},
                                {"dropped_faces", r.dropped.size()},
                                {"flipped_faces", r.flipped_faces}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "wrote " << options.output << ": " << out.polygons.positions.size()
              << " vertices, " << out.polygons.face_count() << " faces (" << r.dropped.size()
              << " degenerate faces dropped, " << r.flipped_faces << " flipped)\n";
  }
  return 0;
}

}  // namespace bisturi::cli
