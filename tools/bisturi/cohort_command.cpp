#include "cohort_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <nlohmann/json.hpp>
#include <regex>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

#include "bisturi/scene/vessel/vessel_phantoms.h"
#include "bisturi/scene/volume/volume_io.h"
#include "pipeline_plan.h"
#include "sha256.h"

namespace bisturi::cli {

namespace fs = std::filesystem;

namespace {

struct CohortCase {
  std::size_t index = 0;
  std::size_t task = 0;
  std::string name;
  std::string scan;  // absolute
};

std::string trim(std::string s) {
  const auto not_space = [](unsigned char c) { return !std::isspace(c); };
  s.erase(s.begin(), std::find_if(s.begin(), s.end(), not_space));
  s.erase(std::find_if(s.rbegin(), s.rend(), not_space).base(), s.end());
  return s;
}

/// One CSV record: fields split at commas outside double quotes ("" is a quote inside).
std::vector<std::string> csv_fields(const std::string& line) {
  std::vector<std::string> out(1);
  bool quoted = false;
  for (std::size_t i = 0; i < line.size(); ++i) {
    const char c = line[i];
    if (quoted) {
      if (c == '"' && i + 1 < line.size() && line[i + 1] == '"') {
        out.back() += '"';
        ++i;
      } else if (c == '"') {
        quoted = false;
      } else {
        out.back() += c;
      }
    } else if (c == '"') {
      quoted = true;
    } else if (c == ',') {
      out.emplace_back();
    } else {
      out.back() += c;
    }
  }
  for (auto& f : out)
    f = trim(f);
  return out;
}

/// The manifest: a header naming the columns `case` and `scan` (others are ignored), then one
/// case per line. Blank lines and lines starting with '#' are skipped, CRLF accepted; scans are
/// relative to the manifest's folder unless absolute.
std::vector<CohortCase> read_manifest(const fs::path& file, std::size_t per_task) {
  std::ifstream in(file);
  if (!in) throw std::runtime_error(file.string() + ": cannot be read");
  static const std::regex name_form(R"(^[A-Za-z0-9_.+-]+$)");
  std::string line;
  std::size_t number = 0;
  int case_col = -1, scan_col = -1;
  std::vector<CohortCase> cases;
  std::set<std::string> names;
  while (std::getline(in, line)) {
    ++number;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    if (number == 1 && line.rfind("\xEF\xBB\xBF", 0) == 0) line.erase(0, 3);  // a UTF-8 BOM
    if (trim(line).empty() || trim(line)[0] == '#') continue;
    const std::vector<std::string> f = csv_fields(line);
    const std::string where = file.string() + ": line " + std::to_string(number) + ": ";
    if (case_col < 0) {
      for (std::size_t i = 0; i < f.size(); ++i) {
        std::string h = f[i];
        std::transform(h.begin(), h.end(), h.begin(),
                       [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
        if (h == "case") case_col = static_cast<int>(i);
        if (h == "scan") scan_col = static_cast<int>(i);
      }
      if (case_col < 0 || scan_col < 0) {
        throw std::runtime_error(where + "the header must name the columns 'case' and 'scan'");
      }
      continue;
    }
    if (static_cast<int>(f.size()) <= std::max(case_col, scan_col)) {
      throw std::runtime_error(where + "expected at least " +
                               std::to_string(std::max(case_col, scan_col) + 1) + " fields");
    }
    CohortCase c;
    c.name = f[static_cast<std::size_t>(case_col)];
    if (!std::regex_match(c.name, name_form)) {
      throw std::runtime_error(where + "case '" + c.name +
                               "': use letters, digits and _ . + - only");
    }
    if (!names.insert(c.name).second) {
      throw std::runtime_error(where + "case '" + c.name + "' is listed twice");
    }
    fs::path scan = f[static_cast<std::size_t>(scan_col)];
    if (scan.empty()) throw std::runtime_error(where + "case '" + c.name + "' has no scan");
    if (scan.is_relative()) scan = file.parent_path() / scan;
    scan = fs::absolute(scan).lexically_normal();
    if (!fs::exists(scan)) {
      throw std::runtime_error(where + "case '" + c.name + "': scan " + scan.string() +
                               " does not exist");
    }
    c.scan = scan.string();
    if (c.scan.find_first_of("\t\n") != std::string::npos) {
      throw std::runtime_error(where + "case '" + c.name + "': the scan's path holds a tab");
    }
    c.index = cases.size();
    c.task = c.index / per_task;
    cases.push_back(std::move(c));
  }
  if (cases.empty()) throw std::runtime_error(file.string() + ": no cases");
  return cases;
}

std::string shell_quote(const std::string& s) {
  std::string out = "'";
  for (const char c : s) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

/// "0,2-4,7" for sorted, unique indices.
std::string ranges(const std::vector<std::size_t>& v) {
  std::string out;
  for (std::size_t i = 0; i < v.size();) {
    std::size_t j = i;
    while (j + 1 < v.size() && v[j + 1] == v[j] + 1)
      ++j;
    if (!out.empty()) out += ",";
    out += std::to_string(v[i]);
    if (j > i) out += "-" + std::to_string(v[j]);
    i = j + 1;
  }
  return out;
}

std::string sbatch_script(const fs::path& dir, const fs::path& bisturi, const PipelinePlan& plan,
                          std::size_t tasks) {
  std::ostringstream s;
  s << "#!/bin/bash\n"
    << "# Written by `bisturi cohort plan`: one array task per " << plan.cases_per_task
    << " case(s) of cases.tsv.\n"
    << "# Submit: sbatch " << (dir / "cohort.sbatch").string() << "\n"
    << "# Gather: " << bisturi.string() << " cohort gather " << dir.string() << "\n"
    << "#SBATCH --job-name=bisturi-cohort\n"
    << "#SBATCH --array=0-" << tasks - 1 << "%" << plan.max_running << "\n"
    << "#SBATCH --ntasks=1\n"
    << "#SBATCH --cpus-per-task=" << plan.cpus_per_task << "\n"
    << "#SBATCH --mem=" << plan.mem_mb << "M\n"
    << "#SBATCH --time=" << plan.time_limit << "\n"
    << "#SBATCH --output=" << (dir / "logs" / "task-%a.job-%A.log").string() << "\n";
  if (!plan.partition.empty()) s << "#SBATCH --partition=" << plan.partition << "\n";
  s << "set -u\n"
    << "cohort=" << shell_quote(dir.string()) << "\n"
    << "bisturi=" << shell_quote(bisturi.string()) << "\n"
    << "task=${SLURM_ARRAY_TASK_ID:?run this script with sbatch (an array task)}\n"
    << "status=0\n"
    << "while IFS=$'\\t' read -r index case_task name scan; do\n"
    << "  [ \"$case_task\" = \"$task\" ] || continue\n"
    << "  echo \"bisturi cohort: task $task, case $index ($name) on ${SLURMD_NODENAME:-$(hostname)}"
       " at $(date -u +%FT%TZ)\"\n"
    << "  \"$bisturi\" pipeline \"$scan\" --plan \"$cohort/plan.toml\" --out "
       "\"$cohort/cases/$name\""
       " --case \"$name\" || status=1\n"
    << "done < <(tail -n +2 \"$cohort/cases.tsv\")\n"
    << "exit $status\n";
  return s.str();
}

void write_text(const fs::path& file, const std::string& text) {
  const fs::path tmp = file.string() + ".partial";
  {
    std::ofstream out(tmp, std::ios::binary | std::ios::trunc);
    out << text;
    if (!out) throw std::runtime_error(tmp.string() + ": cannot be written");
  }
  fs::rename(tmp, file);
}

int run_plan(const CohortOptions& o) {
  const PipelinePlan plan = read_plan(o.plan);
  const fs::path dir = fs::absolute(o.out).lexically_normal();
  static const std::regex safe_dir(R"(^[^\s%'"\\]+$)");
  if (!std::regex_match(dir.string(), safe_dir)) {
    throw std::runtime_error(dir.string() +
                             ": the cohort folder's path may not hold spaces, quotes or '%' "
                             "(#SBATCH lines and Slurm's file patterns cannot carry them)");
  }
  const std::vector<CohortCase> cases =
      read_manifest(o.manifest, static_cast<std::size_t>(plan.cases_per_task));
  const std::size_t tasks = cases.back().task + 1;
  fs::path bisturi = o.bisturi.empty() ? fs::read_symlink("/proc/self/exe") : fs::path(o.bisturi);
  bisturi = fs::absolute(bisturi);
  fs::create_directories(dir / "logs");
  fs::create_directories(dir / "cases");
  fs::copy_file(o.plan, dir / "plan.toml.partial", fs::copy_options::overwrite_existing);
  fs::rename(dir / "plan.toml.partial", dir / "plan.toml");
  std::string tsv = "index\ttask\tcase\tscan\n";
  for (const CohortCase& c : cases)
    tsv += std::to_string(c.index) + "\t" + std::to_string(c.task) + "\t" + c.name + "\t" + c.scan +
           "\n";
  write_text(dir / "cases.tsv", tsv);
  write_text(dir / "cohort.sbatch", sbatch_script(dir, bisturi, plan, tasks));
  fs::permissions(dir / "cohort.sbatch", fs::perms::owner_exec | fs::perms::group_exec,
                  fs::perm_options::add);
  if (o.json) {
    std::cout << nlohmann::json{{"script", (dir / "cohort.sbatch").string()},
                                {"cases", cases.size()},
                                {"tasks", tasks},
                                {"cluster", plan_cluster_json(plan)},
                                {"submit", "sbatch " + (dir / "cohort.sbatch").string()}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "wrote " << (dir / "cohort.sbatch").string() << ": " << cases.size()
              << " cases in " << tasks << " array task(s), at most " << plan.max_running
              << " at once\nsubmit: sbatch " << (dir / "cohort.sbatch").string() << "\n";
  }
  return 0;
}

std::vector<CohortCase> read_cases_tsv(const fs::path& file) {
  std::ifstream in(file);
  if (!in) {
    throw std::runtime_error(file.string() +
                             ": cannot be read (is this a folder that "
                             "`bisturi cohort plan` wrote?)");
  }
  std::vector<CohortCase> cases;
  std::string line;
  std::size_t number = 0;
  while (std::getline(in, line)) {
    if (++number == 1 || line.empty()) continue;
    std::vector<std::string> f;
    std::stringstream ss(line);
    std::string field;
    while (std::getline(ss, field, '\t'))
      f.push_back(field);
    if (f.size() != 4) {
      throw std::runtime_error(file.string() + ": line " + std::to_string(number) +
                               ": expected 4 tab-separated fields");
    }
    CohortCase c;
    try {
      c.index = std::stoul(f[0]);
      c.task = std::stoul(f[1]);
    } catch (const std::exception&) {
      throw std::runtime_error(file.string() + ": line " + std::to_string(number) +
                               ": index and task must be numbers");
    }
    c.name = f[2];
    c.scan = f[3];
    cases.push_back(std::move(c));
  }
  return cases;
}

std::string csv_text(const std::string& s) {
  if (s.find_first_of(",\"\n") == std::string::npos) return s;
  std::string out = "\"";
  for (const char c : s)
    out += c == '"' ? std::string("\"\"") : std::string(1, c);
  return out + "\"";
}

std::string csv_number(const nlohmann::json& v) {
  if (!v.is_number()) return "";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.6g", v.get<double>());
  return buf;
}

int run_gather(const CohortOptions& o) {
  const fs::path dir = fs::absolute(o.out).lexically_normal();
  const std::vector<CohortCase> cases = read_cases_tsv(dir / "cases.tsv");
  int max_running = 8;
  std::string plan_sha;  // a result made with another plan is stale
  if (fs::exists(dir / "plan.toml")) {
    const PipelinePlan plan = read_plan(dir / "plan.toml");
    max_running = plan.max_running;
    plan_sha = sha256_of_text(plan_processing_json(plan).dump());
  }

  std::string sections_csv =
      "case,index,branch,distance_mm,centre_x_mm,centre_y_mm,centre_z_mm,normal_x,normal_y,"
      "normal_z,mean_diameter_mm,equivalent_diameter_mm,min_diameter_mm,max_diameter_mm,area_mm2,"
      "perimeter_mm\n";
  std::string cases_csv =
      "index,task,case,status,error,branches,bifurcations,centreline_length_mm,sections,"
      "diameter_min_mm,diameter_median_mm,diameter_max_mm,total_ms,checksums_ms,read_ms,segment_ms,"
      "surface_ms,centreline_ms,sections_ms,solid_ms,write_ms,scan\n";
  nlohmann::json out_cases = nlohmann::json::array();
  nlohmann::json out_sections = nlohmann::json::array();
  nlohmann::json failed = nlohmann::json::array();
  std::vector<std::size_t> failed_tasks;
  std::size_t ok = 0;
  for (const CohortCase& c : cases) {
    const fs::path file = dir / "cases" / c.name / "result.json";
    std::string status, error;
    nlohmann::json r;
    if (!fs::exists(file)) {
      status = "missing";
      error = "no result.json (the task did not run, or died before it started the case)";
    } else {
      try {
        std::ifstream in(file);
        r = nlohmann::json::parse(in);
        status = r.value("status", "unknown");
      } catch (const std::exception& e) {
        status = "unreadable";
        error = std::string("result.json: ") + e.what();
      }
    }
    if (status == "failed" && r.contains("error")) {
      error = r["error"].value("stage", "") + ": " + r["error"].value("message", "");
    } else if (status == "ok" && !plan_sha.empty() &&
               r["inputs"]["plan"].value("processing_sha256", "") != plan_sha) {
      status = "stale";
      error = "made with another plan than " + (dir / "plan.toml").string();
    } else if (status == "running") {
      status = "incomplete";
      error = "result.json still says running (the task was killed, or is still running)";
    }
    const nlohmann::json fig =
        status == "ok" ? r.value("figures", nlohmann::json::object()) : nlohmann::json::object();
    const auto f = [&](const char* k) {
      return fig.contains(k) ? fig[k] : nlohmann::json(nullptr);
    };
    const nlohmann::json total = r.contains("timings_ms")
                                     ? nlohmann::json(r["timings_ms"].value("total", 0.0))
                                     : nlohmann::json(nullptr);
    cases_csv += std::to_string(c.index) + "," + std::to_string(c.task) + "," + csv_text(c.name) +
                 "," + status + "," + csv_text(error) + "," + csv_number(f("branches")) + "," +
                 csv_number(f("bifurcations")) + "," + csv_number(f("centreline_length_mm")) + "," +
                 csv_number(f("sections")) + "," + csv_number(f("diameter_min_mm")) + "," +
                 csv_number(f("diameter_median_mm")) + "," + csv_number(f("diameter_max_mm")) +
                 "," + csv_number(total) + ",";
    for (const char* stage :
         {"checksums", "read", "segment", "surface", "centreline", "sections", "solid", "write"}) {
      const nlohmann::json t = r.contains("timings_ms") && r["timings_ms"].is_object()
                                   ? r["timings_ms"].value(stage, nlohmann::json(nullptr))
                                   : nlohmann::json(nullptr);
      cases_csv += csv_number(t) + ",";
    }
    cases_csv += csv_text(c.scan) + "\n";
    nlohmann::json entry = {{"index", c.index},
                            {"task", c.task},
                            {"case", c.name},
                            {"scan", c.scan},
                            {"status", status},
                            {"figures", fig},
                            {"timings_ms", r.value("timings_ms", nlohmann::json(nullptr))}};
    if (!error.empty()) entry["error"] = error;
    out_cases.push_back(entry);
    if (status != "ok") {
      failed.push_back(
          {{"index", c.index},
           {"task", c.task},
           {"case", c.name},
           {"error", error},
           {"log", (dir / "logs").string() + "/task-" + std::to_string(c.task) + ".job-*.log"}});
      failed_tasks.push_back(c.task);
      continue;
    }
    ++ok;
    for (const auto& s : r.value("sections", nlohmann::json::array())) {
      const auto& cm = s["centre_mm"];
      const auto& n = s["normal"];
      sections_csv += csv_text(c.name) + "," + std::to_string(c.index) + "," +
                      csv_number(s["branch"]) + "," + csv_number(s["distance_mm"]) + "," +
                      csv_number(cm[0]) + "," + csv_number(cm[1]) + "," + csv_number(cm[2]) + "," +
                      csv_number(n[0]) + "," + csv_number(n[1]) + "," + csv_number(n[2]) + "," +
                      csv_number(s["mean_diameter_mm"]) + "," +
                      csv_number(s["equivalent_diameter_mm"]) + "," +
                      csv_number(s["min_diameter_mm"]) + "," + csv_number(s["max_diameter_mm"]) +
                      "," + csv_number(s["area_mm2"]) + "," + csv_number(s["perimeter_mm"]) + "\n";
      nlohmann::json row = s;
      row["case"] = c.name;
      row["index"] = c.index;
      out_sections.push_back(row);
    }
  }
  std::sort(failed_tasks.begin(), failed_tasks.end());
  failed_tasks.erase(std::unique(failed_tasks.begin(), failed_tasks.end()), failed_tasks.end());
  const std::string rerun = failed_tasks.empty() ? std::string()
                                                 : "sbatch --array=" + ranges(failed_tasks) + "%" +
                                                       std::to_string(max_running) + " " +
                                                       (dir / "cohort.sbatch").string();
  write_text(dir / "cohort.csv", sections_csv);
  write_text(dir / "cohort_cases.csv", cases_csv);
  const nlohmann::json summary = {
      {"cohort", dir.string()},
      {"cases", cases.size()},
      {"ok", ok},
      {"not_ok", cases.size() - ok},
      {"failed", failed},
      {"rerun", failed_tasks.empty() ? nlohmann::json(nullptr) : nlohmann::json(rerun)},
      {"tables",
       {{"sections_csv", (dir / "cohort.csv").string()},
        {"cases_csv", (dir / "cohort_cases.csv").string()}}}};
  nlohmann::json all = summary;
  all["case_results"] = out_cases;
  all["sections"] = out_sections;
  write_text(dir / "cohort.json", all.dump(2) + "\n");
  if (o.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << dir.string() << ": " << ok << " of " << cases.size() << " cases ok, "
              << out_sections.size() << " sections -> " << (dir / "cohort.csv").string() << ", "
              << (dir / "cohort_cases.csv").string() << ", " << (dir / "cohort.json").string()
              << "\n";
    for (const auto& fcase : failed) {
      std::cout << "  not ok: case " << fcase["index"] << " (" << fcase["case"].get<std::string>()
                << ", task " << fcase["task"] << "): " << fcase["error"].get<std::string>() << "\n";
    }
    if (!rerun.empty()) std::cout << "rerun them: " << rerun << "\n";
  }
  return ok == cases.size() ? 0 : 3;
}

int run_phantoms(const CohortOptions& o) {
  const fs::path dir = fs::absolute(o.out).lexically_normal();
  fs::create_directories(dir / "scans");
  const VesselShape shapes[] = {VesselShape::Straight, VesselShape::Curved, VesselShape::Tapering,
                                VesselShape::Bifurcating};
  std::string manifest = "case,scan,shape\n";
  std::string truth = "case,piece,ax_mm,ay_mm,az_mm,bx_mm,by_mm,bz_mm,radius_a_mm,radius_b_mm\n";
  char buf[512];
  for (int i = 0; i < o.count; ++i) {
    VesselPhantomOptions p;
    p.shape = shapes[i % 4];
    p.radius_mm = 3.0 + 0.5 * ((i / 4) % 3);
    p.length_mm = 40.0;
    if (p.shape == VesselShape::Tapering) {
      p.end_radius_mm = p.radius_mm;  // narrow first: the start must be found at the wide end
      p.radius_mm += 1.5;
      std::swap(p.radius_mm, p.end_radius_mm);
    }
    if (p.shape == VesselShape::Bifurcating) {
      p.radius_mm += 0.5;
      p.length_mm = 50.0;
    }
    p.spacing = glm::dvec3(o.spacing_mm);
    p.noise_hu = o.noise_hu;
    if (o.field_of_view_mm.size() == 3) {
      p.field_of_view_mm =
          glm::dvec3(o.field_of_view_mm[0], o.field_of_view_mm[1], o.field_of_view_mm[2]);
    }
    p.seed = static_cast<unsigned>(i + 1);
    p.tilt_degrees = 7.0 + 3.0 * i;
    const VesselPhantom ph = make_vessel_phantom(p);
    std::snprintf(buf, sizeof buf, "case-%02d", i);
    const std::string name = buf;
    write_nrrd(dir / "scans" / (name + ".nrrd"), ph.volume, NrrdEncoding::Gzip);
    manifest += name + ",scans/" + name + ".nrrd," + std::string(to_string(p.shape)) + "\n";
    for (std::size_t k = 0; k < ph.axis.size(); ++k) {
      const AxisPiece& a = ph.axis[k];
      std::snprintf(buf, sizeof buf, "%s,%zu,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f,%.6f\n",
                    name.c_str(), k, a.a.x, a.a.y, a.a.z, a.b.x, a.b.y, a.b.z, a.radius_a,
                    a.radius_b);
      truth += buf;
    }
  }
  write_text(dir / "manifest.csv", manifest);
  write_text(dir / "truth.csv", truth);
  write_text(dir / "plan.toml",
             "# A plan for the phantoms (lumen 300 HU, background 0 HU): everything at or above\n"
             "# the mid value is lumen; the largest object is the vessel.\n"
             "[segmentation]\nmethod = \"threshold\"\nrange = [150.0, 2000.0]\n\n"
             "[surface]\nsmooth = 3\ndecimate = 0.25\n\n"
             "[centreline]\nsection_step_mm = 2.0\n\n"
             "[cluster]\ncases_per_task = 1\nmax_running = 3\ncpus_per_task = 1\nmem_mb = 500\n"
             "time_limit = \"00:05:00\"\n");
  if (o.json) {
    std::cout << nlohmann::json{{"cohort", dir.string()},
                                {"cases", o.count},
                                {"manifest", (dir / "manifest.csv").string()},
                                {"truth", (dir / "truth.csv").string()},
                                {"plan", (dir / "plan.toml").string()}}
                     .dump(2)
              << "\n";
  } else {
    std::cout << "wrote " << o.count << " vessel phantoms to " << (dir / "scans").string() << ", "
              << (dir / "manifest.csv").string() << ", " << (dir / "truth.csv").string() << ", "
              << (dir / "plan.toml").string() << "\n";
  }
  return 0;
}

}  // namespace

void add_cohort_command(CLI::App& app, CohortOptions& options, int (*&run)(const CohortOptions&)) {
  CLI::App* cohort = app.add_subcommand(
      "cohort", "run `bisturi pipeline` over a cohort of scans on a Slurm cluster (job arrays)");
  cohort->require_subcommand(1);
  using Action = CohortOptions::Action;

  CLI::App* plan = cohort->add_subcommand(
      "plan", "write a Slurm batch script (a job array over the manifest's cases) into DIR");
  plan->add_option("MANIFEST", options.manifest, "CSV with the columns case and scan")
      ->required()
      ->check(CLI::ExistingFile);
  plan->add_option("--plan", options.plan, "the pipeline plan (TOML; [cluster] sets resources)")
      ->required()
      ->check(CLI::ExistingFile);
  plan->add_option("--out", options.out, "the cohort's folder (created)")->required();
  plan->add_option("--bisturi", options.bisturi,
                   "the bisturi program the tasks run (default: this one)");
  plan->add_flag("--json", options.json, "write a JSON summary on stdout");
  plan->callback([&run, &options] {
    options.action = Action::Plan;
    run = run_cohort;
  });

  CLI::App* gather = cohort->add_subcommand(
      "gather",
      "collect every case's result.json into one table (CSV, JSON); list the cases "
      "that are not ok with the command that reruns exactly them (exit 3 if any)");
  gather->add_option("DIR", options.out, "the cohort's folder (from `cohort plan`)")
      ->required()
      ->check(CLI::ExistingDirectory);
  gather->add_flag("--json", options.json, "write the summary as JSON on stdout");
  gather->callback([&run, &options] {
    options.action = Action::Gather;
    run = run_cohort;
  });

  CLI::App* phantoms = cohort->add_subcommand(
      "phantoms", "write a small cohort of vessel phantoms with their truth (examples, tests)");
  phantoms->add_option("--out", options.out, "folder (created)")->required();
  phantoms
      ->add_option("--count", options.count,
                   "cases (shapes cycle: straight, curved, "
                   "tapering, bifurcating)")
      ->check(CLI::Range(1, 1000));
  phantoms->add_option("--spacing", options.spacing_mm, "voxel size (mm)")
      ->check(CLI::Range(0.1, 5.0));
  phantoms->add_option("--noise", options.noise_hu, "Gaussian noise (HU; lumen 300, background 0)")
      ->check(CLI::Range(0.0, 200.0));
  phantoms
      ->add_option("--fov", options.field_of_view_mm,
                   "each scan's extent X Y Z (mm) at least, the vessel in its middle (a CT's "
                   "field of view; default: the vessel's box)")
      ->expected(3)
      ->check(CLI::Range(0.0, 2000.0));
  phantoms->add_flag("--json", options.json, "write a JSON summary on stdout");
  phantoms->callback([&run, &options] {
    options.action = Action::Phantoms;
    run = run_cohort;
  });
}

int run_cohort(const CohortOptions& options) {
  switch (options.action) {
    case CohortOptions::Action::Plan:
      return run_plan(options);
    case CohortOptions::Action::Gather:
      return run_gather(options);
    case CohortOptions::Action::Phantoms:
      return run_phantoms(options);
    case CohortOptions::Action::None:
      break;
  }
  return 2;
}

}  // namespace bisturi::cli
