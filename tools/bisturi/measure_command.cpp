#include "measure_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/measure/plane_cut.h"
#include "bisturi/scene/measure/section_measures.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume_io.h"
#include "progress_line.h"
#include "stopwatch.h"

namespace bisturi::cli {

namespace {

bool is_mesh_file(const std::string& path) {
  std::string ext = std::filesystem::path(path).extension().string();
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return ext == ".obj" || ext == ".ply" || ext == ".stl" || ext == ".off";
}

nlohmann::json vec(const glm::dvec3& v) {
  return nlohmann::json::array({v.x, v.y, v.z});
}

nlohmann::json loop_json(const LoopMeasures& m) {
  return {{"closed", m.closed},
          {"centroid", vec(m.centroid)},
          {"area", m.area},
          {"perimeter", m.perimeter},
          {"mean_diameter", m.mean_diameter},
          {"equivalent_diameter", m.equivalent_diameter},
          {"min_caliper", m.min_caliper},
          {"max_caliper", m.max_caliper},
          {"normal", vec(m.normal)},
          {"faces_touched", m.faces_touched},
          {"points", m.points}};
}

}  // namespace

void add_measure_command(CLI::App& app, MeasureCommandOptions& options,
                         int (*&run)(const MeasureCommandOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "measure",
      "cut a vessel surface (mesh file, or a volume extracted first) with planes and measure "
      "every cross-section loop: centroid, area, perimeter, diameters, calipers (mm)");
  cmd->add_option("INPUT", options.input,
                  "mesh (.obj .ply .stl .off) or volume (NRRD, NIfTI, DICOM folder)")
      ->required()
      ->check(CLI::ExistingPath);
  cmd->add_option("--plane", options.planes,
                  "a plane: point PX PY PZ and normal NX NY NZ (world mm); repeat for more")
      ->expected(6)
      ->required();
  cmd->add_flag("--orthogonal", options.orthogonal,
                "search, from each plane's point and normal, the plane through the point with "
                "the smallest section (the true orthogonal section of a bent vessel)");
  cmd->add_option("--iso", options.iso,
                  "volume input: surface where the value crosses VALUE "
                  "(inside: value > VALUE; default 0)");
  cmd->add_flag("--linear", options.linear,
                "volume input: linear vertex placement (classic marching cubes) instead of cubic");
  cmd->add_flag("--polygon", options.polygon,
                "measure the raw cut polygons (no surface correction, no smooth curve)");
  cmd->add_flag("--json", options.json, "write the sections as one JSON object on stdout");
  cmd->callback([&run] { run = run_measure; });
}

int run_measure(const MeasureCommandOptions& options) {
  for (const auto& p : options.planes) {
    if (p.size() != 6) throw InputError("--plane needs six numbers: PX PY PZ NX NY NZ");
  }
  ProgressLine line;
  Dlfl mesh;
  auto t = Clock::now();
  if (is_mesh_file(options.input)) {
    const MeshFile file = read_mesh(options.input);
    for (const std::string& w : file.warnings)
      std::cerr << "bisturi: warning: " << w << "\n";
    ImportOptions import;
    import.weld = !file.has_vertex_list;  // an STL soup shares no vertices until welded
    mesh = import_polygons(file.polygons, file.has_vertex_list, import).mesh;
    line.done("read and import " + options.input, milliseconds_since(t));
  } else {
    VolumeReadOptions read_options;
    read_options.progress = [&](std::size_t done, std::size_t total) {
      line.show("read", done, total);
    };
    const Volume volume = read_volume(options.input, read_options);
    line.done("read " + options.input, milliseconds_since(t));
    if (!std::isfinite(options.iso)) throw InputError("--iso: the value must be finite");
    IsoSurfaceOptions iso;
    iso.iso = static_cast<float>(options.iso);
    iso.placement = options.linear ? VertexPlacement::Linear : VertexPlacement::Cubic;
    iso.progress = [&](std::size_t done, std::size_t total) { line.show("surface", done, total); };
    iso.build_progress = [&](std::size_t done, std::size_t total) {
      line.show("solid (DLFL)", done, total);
    };
    t = Clock::now();
    mesh = extract_isosurface(volume, iso);
    line.done("surface and solid", milliseconds_since(t));
  }
  const double load_ms = milliseconds_since(t);

  t = Clock::now();
  const CutIndex index(mesh);
  const double index_ms = milliseconds_since(t);
  bisturi::MeasureOptions measure;
  CutOptions cut_options;
  if (options.polygon) {
    measure.smooth = false;
    measure.use_surface_points = false;
    cut_options.surface_points = false;
  }

  nlohmann::json sections = nlohmann::json::array();
  for (const auto& p : options.planes) {
    const glm::dvec3 point(p[0], p[1], p[2]), normal(p[3], p[4], p[5]);
    nlohmann::json section;
    nlohmann::json loops = nlohmann::json::array();
    t = Clock::now();
    if (options.orthogonal) {
      OrthogonalOptions o;
      o.cut = cut_options;
      o.measure = measure;
      const OrthogonalSection s = find_orthogonal_section(index, point, normal, o);
      if (s.found) loops.push_back(loop_json(s.measures));
      section = {{"point", vec(s.plane.point)},
                 {"normal", vec(s.plane.normal)},
                 {"given_normal", vec(glm::normalize(normal))},
                 {"tilt_degrees", s.tilt_degrees},
                 {"cuts", s.evaluations},
                 {"faces_touched", s.found ? s.measures.faces_touched : 0}};
    } else {
      const PlaneCut cut = index.cut({point, normal}, cut_options);
      for (const LoopMeasures& m : measure_cut(cut, measure))
        loops.push_back(loop_json(m));
      section = {{"point", vec(cut.plane.point)},
                 {"normal", vec(cut.plane.normal)},
                 {"faces_touched", cut.faces_touched}};
    }
    section["loops"] = loops;
    section["time_ms"] = milliseconds_since(t);
    sections.push_back(section);
  }
  line.clear();

  if (options.json) {
    const nlohmann::json out = {{"input", options.input},
                                {"faces", mesh.num_faces()},
                                {"orthogonal", options.orthogonal},
                                {"sections", sections},
                                {"times_ms", {{"load", load_ms}, {"index", index_ms}}}};
    std::cout << out.dump(2) << "\n";
    return 0;
  }
  std::cout << options.input << ": " << mesh.num_faces() << " faces\n";
  std::size_t k = 0;
  for (const auto& s : sections) {
    const auto& pt = s["point"];
    const auto& n = s["normal"];
    std::cout << "plane " << ++k << ": point (" << pt[0] << ", " << pt[1] << ", " << pt[2]
              << "), normal (" << n[0] << ", " << n[1] << ", " << n[2] << ")";
    if (options.orthogonal) std::cout << ", tilted " << s["tilt_degrees"] << " deg";
    std::cout << ": " << s["loops"].size() << " loop(s)\n";
    for (const auto& l : s["loops"]) {
      const auto& c = l["centroid"];
      std::cout << "  " << (l["closed"].get<bool>() ? "closed" : "open") << " loop: centroid ("
                << c[0] << ", " << c[1] << ", " << c[2] << "), area " << l["area"]
                << " mm2, perimeter " << l["perimeter"] << " mm, mean diameter "
                << l["mean_diameter"] << " mm, equivalent diameter " << l["equivalent_diameter"]
                << " mm, calipers " << l["min_caliper"] << " .. " << l["max_caliper"] << " mm, "
                << l["faces_touched"] << " faces\n";
    }
  }
  return 0;
}

}  // namespace bisturi::cli
