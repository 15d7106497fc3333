#include "pipeline_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <nlohmann/json.hpp>
#include <regex>
#include <stdexcept>
#include <string>

#include "bisturi/runtime/version.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/vessel/centreline.h"
#include "bisturi/scene/vessel/vessel_sections.h"
#include "bisturi/scene/volume/volume_io.h"
#include "pipeline_plan.h"
#include "pipeline_stages.h"
#include "progress_line.h"
#include "sha256.h"
#include "stopwatch.h"

namespace bisturi::cli {

namespace fs = std::filesystem;

namespace {

constexpr const char* kResultFormat = "bisturi-pipeline-result/1";

nlohmann::json vec(const glm::dvec3& v) {
  return nlohmann::json::array({v.x, v.y, v.z});
}

std::string default_case_name(const fs::path& scan) {
  std::string name = scan.filename().string();
  if (name.empty()) name = scan.parent_path().filename().string();  // a folder given with '/'
  for (const char* ext : {".nii.gz", ".nrrd", ".nhdr", ".nii", ".gz"}) {
    const std::string e(ext);
    if (name.size() > e.size() && name.compare(name.size() - e.size(), e.size(), e) == 0) {
      name.resize(name.size() - e.size());
      break;
    }
  }
  return name;
}

/// Writes `text` to `file` through a temporary name in the same folder and a rename, so the
/// file is either the old one or the whole new one.
void write_atomically(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    out.flush();
    if (!out) throw std::runtime_error(tmp.string() + ": cannot be written");
  }
  fs::rename(tmp, file);
}

struct Stage {
  std::string name;
  double ms = 0.0;
};

/// Runs the stages, timing each; the name of the stage that threw is kept for the result.
class StageClock {
 public:
  explicit StageClock(ProgressLine& line) : line_(line) {}
  template <class F>
  auto run(const std::string& name, F&& f) {
    current_ = name;
    const auto t = Clock::now();
    if constexpr (std::is_void_v<decltype(f())>) {
      f();
      finish(name, milliseconds_since(t));
    } else {
      auto r = f();
      finish(name, milliseconds_since(t));
      return r;
    }
  }
  [[nodiscard]] const std::string& current() const { return current_; }
  [[nodiscard]] nlohmann::json json() const {
    nlohmann::json j = nlohmann::json::object();
    double total = 0.0;
    for (const Stage& s : stages_) {
      j[s.name] = s.ms;
      total += s.ms;
    }
    j["total"] = total;
    return j;
  }

 private:
  void finish(const std::string& name, double ms) {
    stages_.push_back({name, ms});
    line_.done(name, ms);
  }
  ProgressLine& line_;
  std::vector<Stage> stages_;
  std::string current_;
};

nlohmann::json centreline_json(const Centreline& c, const RecentreStats& r) {
  nlohmann::json branches = nlohmann::json::array();
  for (const CentrelineBranch& b : c.branches) {
    nlohmann::json points = nlohmann::json::array();
    for (const glm::dvec3& p : b.points)
      points.push_back(vec(p));
    branches.push_back({{"id", b.id},
                        {"parent", b.parent},
                        {"start_distance_mm", b.distance_mm.front()},
                        {"length_mm", b.length_mm()},
                        {"ends_at", b.ends_at_tip ? "tip" : "bifurcation"},
                        {"points_mm", points}});
  }
  nlohmann::json bif = nlohmann::json::array();
  for (const glm::dvec3& p : c.bifurcations)
    bif.push_back(vec(p));
  return {{"branches", branches},
          {"bifurcations_mm", bif},
          {"pruned_branches", c.pruned_branches},
          {"recentred_points", r.moved},
          {"kept_points", r.kept},
          {"max_recentring_mm", r.max_move_mm}};
}

nlohmann::json sections_json(const std::vector<VesselSection>& sections) {
  nlohmann::json out = nlohmann::json::array();
  for (const VesselSection& s : sections) {
    out.push_back({{"branch", s.branch},
                   {"distance_mm", s.distance_mm},
                   {"centre_mm", vec(s.centre)},
                   {"normal", vec(s.normal)},
                   {"mean_diameter_mm", s.measures.mean_diameter},
                   {"equivalent_diameter_mm", s.measures.equivalent_diameter},
                   {"min_diameter_mm", s.measures.min_caliper},
                   {"max_diameter_mm", s.measures.max_caliper},
                   {"area_mm2", s.measures.area},
                   {"perimeter_mm", s.measures.perimeter},
                   {"tilt_degrees", s.tilt_degrees}});
  }
  return out;
}

std::string centreline_csv(const Centreline& c) {
  std::string out = "branch,parent,distance_mm,x_mm,y_mm,z_mm,radius_mm\n";
  char line[256];
  for (const CentrelineBranch& b : c.branches) {
    for (std::size_t k = 0; k < b.points.size(); ++k) {
      std::snprintf(line, sizeof line, "%d,%d,%.4f,%.4f,%.4f,%.4f,%.4f\n", b.id, b.parent,
                    b.distance_mm[k], b.points[k].x, b.points[k].y, b.points[k].z, b.radius_mm[k]);
      out += line;
    }
  }
  return out;
}

std::string scene_solid_toml(const std::string& case_name) {
  return "# A [[solids]] entry for a bisturi scene file: the vessel of case " + case_name +
         ",\n# already smoothed and decimated by `bisturi pipeline` (world LPS mm). Copy it into "
         "a\n"
         "# scene next to vessel.obj, or give the path to vessel.obj from the scene's folder.\n"
         "[[solids]]\nname = \"" +
         case_name +
         "\"\nmesh = \"vessel.obj\"\ndecimate = 1.0\n"
         "smooth = 0\n\n[solids.material]\nstiffness_N_per_m = 900.0\n"
         "damping_N_s_per_m = 1.0\ndensity_kg_per_m3 = 1060.0\ncolour = [0.70, 0.12, 0.15]\n";
}

/// An ok result.json for exactly this key whose files are all there: the case is done.
bool up_to_date(const fs::path& result_file, const std::string& key, nlohmann::json& result) {
  std::ifstream in(result_file);
  if (!in) return false;
  try {
    result = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception&) {
    return false;
  }
  if (result.value("status", "") != "ok" || result.value("key", "") != key) return false;
  if (!result.contains("files") || !result["files"].is_object()) return false;
  for (const auto& [name, f] : result["files"].items()) {
    if (!f.is_string() || !fs::exists(result_file.parent_path() / f.get<std::string>()))
      return false;
  }
  return true;
}

void print_summary(const nlohmann::json& r) {
  const auto& f = r["figures"];
  const auto num = [](const nlohmann::json& v) { return v.is_number() ? v.get<double>() : 0.0; };
  std::printf(
      "%s: %d branch(es), %d bifurcation(s), centreline %.1f mm, %d sections, mean "
      "diameter %.2f .. %.2f mm (median %.2f)\n  times (ms):",
      r["case"].get<std::string>().c_str(), f["branches"].get<int>(), f["bifurcations"].get<int>(),
      num(f["centreline_length_mm"]), f["sections"].get<int>(), num(f["diameter_min_mm"]),
      num(f["diameter_max_mm"]), num(f["diameter_median_mm"]));
  for (const char* stage : {"checksums", "read", "segment", "surface", "centreline", "sections",
                            "solid", "write", "total"}) {
    if (r["timings_ms"].contains(stage))
      std::printf(" %s %.1f", stage, r["timings_ms"][stage].get<double>());
  }
  std::printf("\n");
}

}  // namespace

void add_pipeline_command(CLI::App& app, PipelineOptions& options,
                          int (*&run)(const PipelineOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "pipeline",
      "one scan, unattended: segment the vessel, extract its surface, trace its centreline, "
      "measure sections along it and make the session solid, all as a plan (TOML) says; "
      "writes result.json, the meshes and a diameter plot into DIR and nothing elsewhere");
  cmd->add_option("SCAN", options.scan, "volume file (NRRD, NIfTI) or a folder of DICOM slices")
      ->required();
  cmd->add_option("--plan", options.plan, "the plan (TOML; README: cohorts)")->required();
  cmd->add_option("--out", options.out, "the case's folder (created)")->required();
  cmd->add_option("--case", options.case_name,
                  "the case's name in result.json (default: the scan's file name)");
  cmd->add_flag("--force", options.force, "redo the case even when its result is up to date");
  cmd->add_flag("--json", options.json, "write result.json's content on stdout too");
  cmd->callback([&run] { run = run_pipeline; });
}

int run_pipeline(const PipelineOptions& options) {
  const fs::path dir(options.out);
  fs::create_directories(dir);
  const fs::path result_file = dir / "result.json";
  const std::string case_name =
      options.case_name.empty() ? default_case_name(options.scan) : options.case_name;
  static const std::regex name_form(R"(^[A-Za-z0-9_.+-]+$)");
  if (!std::regex_match(case_name, name_form)) {
    throw std::runtime_error("case name '" + case_name +
                             "': use letters, digits and _ . + - only (give --case)");
  }

  ProgressLine line(!options.json);
  StageClock clock(line);
  nlohmann::json result = {{"format", kResultFormat},
                           {"case", case_name},
                           {"tool", {{"name", "bisturi"}, {"version", kVersion}}},
                           {"inputs",
                            {{"scan", {{"path", fs::absolute(options.scan).string()}}},
                             {"plan", {{"path", fs::absolute(options.plan).string()}}}}}};
  const auto fail = [&](const std::string& stage, const std::string& message) {
    result["status"] = "failed";
    result["error"] = {{"stage", stage}, {"message", message}};
    result["timings_ms"] = clock.json();
    result.erase("files");
    write_atomically(result_file, result.dump(2) + "\n");
    if (options.json) std::cout << result.dump(2) << "\n";
    std::cerr << "bisturi: error: case " << case_name << ": " << stage << ": " << message << "\n";
    return 1;
  };

  PipelinePlan plan;
  std::string key;
  try {
    plan = clock.run("checksums", [&] {
      PipelinePlan p = read_plan(options.plan);
      const std::string plan_text = plan_processing_json(p).dump();
      const std::string scan_sha = sha256_of_path(options.scan);
      result["inputs"]["scan"]["sha256"] = scan_sha;
      result["inputs"]["plan"]["sha256"] = sha256_of_path(options.plan);
      result["inputs"]["plan"]["processing_sha256"] = sha256_of_text(plan_text);
      key = sha256_of_text(scan_sha + "\n" + plan_text + "\n" + kVersion);
      return p;
    });
  } catch (const std::exception& e) {
    return fail(clock.current(), e.what());
  }
  result["key"] = key;
  result["plan"] = plan_processing_json(plan);

  nlohmann::json previous;
  if (!options.force && up_to_date(result_file, key, previous)) {
    if (options.json) {
      std::cout << previous.dump(2) << "\n";
    } else {
      std::cout << case_name << ": up to date (" << result_file.string() << ")\n";
    }
    return 0;
  }
  result["status"] = "running";
  write_atomically(result_file, result.dump(2) + "\n");

  try {
    const Volume volume = clock.run("read", [&] {
      VolumeReadOptions read;
      read.progress = [&](std::size_t done, std::size_t total) { line.show("read", done, total); };
      return read_volume(options.scan, read);
    });
    const VolumeGeometry& g = volume.geometry;
    result["volume"] = {{"dims", g.dims},
                        {"spacing_mm", vec(g.spacing)},
                        {"origin_mm", vec(g.origin)},
                        {"world_frame", "LPS mm"}};

    const VesselMask vessel = clock.run("segment", [&] { return segment_vessel(volume, plan); });
    const double voxel_mm3 = g.spacing.x * g.spacing.y * g.spacing.z;

    ExtractionStats extraction;
    const Dlfl surface = clock.run("surface", [&] {
      SurfaceField f = surface_field(volume, vessel, plan);
      f.iso.progress = [&](std::size_t done, std::size_t total) {
        line.show("surface", done, total);
      };
      return extract_isosurface(f.field, f.iso, &extraction);
    });
    if (surface.num_faces() == 0) throw std::runtime_error("the vessel has no surface");

    Centreline centreline = clock.run("centreline", [&] {
      CentrelineOptions o;
      o.min_branch_mm = plan.min_branch_mm;
      if (plan.start_mm) {
        o.start_mm = glm::dvec3((*plan.start_mm)[0], (*plan.start_mm)[1], (*plan.start_mm)[2]);
      }
      return extract_centreline(vessel.mask, o);
    });

    RecentreStats recentred;
    const SectionsResult sections = clock.run("sections", [&] {
      const CutIndex index(surface);
      recentred = recentre_on_surface(index, centreline);
      SectionOptions o;
      o.step_mm = plan.section_step_mm;
      o.end_margin_radii = plan.end_margin_radii;
      o.junction_margin_radii = plan.junction_margin_radii;
      o.orthogonal_search = plan.orthogonal;
      return measure_sections(index, centreline, o);
    });

    const ExportedPolygons solid = clock.run("solid", [&] {
      Dlfl mesh = surface;
      if (plan.smooth > 0) {
        lod::SmoothOptions s;
        s.iterations = static_cast<std::size_t>(plan.smooth);
        lod::smooth_taubin(mesh, s);
      }
      if (plan.decimate < 1.0) {
        lod::DecimateOptions d;
        d.target_faces = std::max<std::size_t>(
            4, static_cast<std::size_t>(std::llround(
                   plan.decimate * static_cast<double>(lod::polygon_face_count(mesh)))));
        d.progress = [&](std::size_t done, std::size_t total) {
          line.show("decimate", done, total);
        };
        lod::decimate(mesh, d);
        mesh.compact();
      }
      return export_polygons(mesh);
    });

    clock.run("write", [&] {
      const ExportedPolygons measured = export_polygons(surface);
      write_ply(dir / "surface.ply.partial", measured.polygons);
      fs::rename(dir / "surface.ply.partial", dir / "surface.ply");
      write_obj(dir / "vessel.obj.partial", solid.polygons);
      fs::rename(dir / "vessel.obj.partial", dir / "vessel.obj");
      write_atomically(dir / "scene_solid.toml", scene_solid_toml(case_name));
      write_atomically(dir / "centreline.csv", centreline_csv(centreline));
      write_profile_png(dir / "profile.png.partial", case_name + ": mean diameter along the vessel",
                        sections.sections, centreline.branches.size(), plan.section_step_mm);
      fs::rename(dir / "profile.png.partial", dir / "profile.png");
    });

    std::vector<double> diameters;
    for (const VesselSection& s : sections.sections)
      diameters.push_back(s.measures.mean_diameter);
    std::sort(diameters.begin(), diameters.end());
    double length = 0.0;
    for (const CentrelineBranch& b : centreline.branches)
      length += b.length_mm();
    const auto or_null = [&](double v) {
      return diameters.empty() ? nlohmann::json(nullptr) : nlohmann::json(v);
    };
    result["figures"] = {
        {"lumen_voxels", vessel.voxels},
        {"lumen_volume_mm3", static_cast<double>(vessel.voxels) * voxel_mm3},
        {"objects_in_range", vessel.objects_in_range},
        {"segmented_by", vessel.how},
        {"surface_faces", surface.num_faces()},
        {"solid_faces", solid.polygons.face_count()},
        {"solid_vertices", solid.polygons.positions.size()},
        {"branches", centreline.branches.size()},
        {"bifurcations", centreline.bifurcations.size()},
        {"centreline_length_mm", length},
        {"max_radius_mm", centreline.max_radius_mm},
        {"sections", sections.sections.size()},
        {"sections_without_loop", sections.skipped_no_loop},
        {"diameter_min_mm", or_null(diameters.empty() ? 0.0 : diameters.front())},
        {"diameter_max_mm", or_null(diameters.empty() ? 0.0 : diameters.back())},
        {"diameter_median_mm", or_null(diameters.empty() ? 0.0 : diameters[diameters.size() / 2])}};
    result["centreline"] = centreline_json(centreline, recentred);
    result["sections"] = sections_json(sections.sections);
    result["files"] = {{"surface", "surface.ply"},
                       {"solid", "vessel.obj"},
                       {"scene_solid", "scene_solid.toml"},
                       {"centreline", "centreline.csv"},
                       {"profile_plot", "profile.png"}};
  } catch (const std::exception& e) {
    return fail(clock.current(), e.what());
  }
  result["status"] = "ok";
  result["timings_ms"] = clock.json();
  write_atomically(result_file, result.dump(2) + "\n");
  if (options.json) {
    std::cout << result.dump(2) << "\n";
  } else {
    print_summary(result);
  }
  return 0;
}

}  // namespace bisturi::cli
