#include "pipeline_plan.h"

#include <toml++/toml.h>

#include <cmath>
#include <filesystem>
#include <initializer_list>
#include <regex>
#include <stdexcept>

namespace bisturi::cli {

namespace {

class PlanReader {
 public:
  explicit PlanReader(std::string name) : name_(std::move(name)) {}

  PipelinePlan read(const toml::table& root) {
    PipelinePlan p;
    only_keys(root, "", {"segmentation", "surface", "centreline", "cluster"});
    if (const toml::table* t = table(root, "segmentation")) {
      only_keys(*t, "segmentation", {"method", "range", "label", "seed_mm", "connectivity"});
      p.method = string_or(*t, "segmentation.method", "method", p.method);
      if (p.method != "threshold" && p.method != "window" && p.method != "label") {
        fail(t->get("method"), *t, "segmentation.method",
             "expected \"threshold\", \"window\" or \"label\"");
      }
      if (const auto v = numbers<2>(*t, "segmentation.range", "range")) p.range = *v;
      if (p.method == "threshold" && !(p.range[0] <= p.range[1])) {
        fail(t->get("range"), *t, "segmentation.range", "expected [lo, hi] with lo <= hi");
      }
      if (p.method == "window" && !(p.range[1] >= 0.0)) {
        fail(t->get("range"), *t, "segmentation.range", "expected [centre, width] with width >= 0");
      }
      p.label = integer(*t, "segmentation.label", "label", p.label, 1, 0xffffff);
      if (p.method == "label" && t->contains("range")) {
        fail(t->get("range"), *t, "segmentation.range", "not used with method = \"label\"");
      }
      p.seed_mm = numbers<3>(*t, "segmentation.seed_mm", "seed_mm");
      p.connectivity =
          static_cast<int>(integer(*t, "segmentation.connectivity", "connectivity", 26, 6, 26));
      if (p.connectivity != 6 && p.connectivity != 26) {
        fail(t->get("connectivity"), *t, "segmentation.connectivity", "expected 6 or 26");
      }
    }
    if (const toml::table* t = table(root, "surface")) {
      only_keys(*t, "surface", {"smooth", "decimate"});
      p.smooth = static_cast<int>(integer(*t, "surface.smooth", "smooth", p.smooth, 0, 1000));
      p.decimate = number(*t, "surface.decimate", "decimate", p.decimate);
      if (!(p.decimate > 0.0 && p.decimate <= 1.0)) {
        fail(t->get("decimate"), *t, "surface.decimate", "must be in (0, 1]");
      }
    }
    if (const toml::table* t = table(root, "centreline")) {
      only_keys(*t, "centreline",
                {"section_step_mm", "min_branch_mm", "start_mm", "end_margin_radii",
                 "junction_margin_radii", "orthogonal"});
      p.section_step_mm =
          number(*t, "centreline.section_step_mm", "section_step_mm", p.section_step_mm);
      if (!(p.section_step_mm >= 0.05)) {
        fail(t->get("section_step_mm"), *t, "centreline.section_step_mm", "must be >= 0.05 mm");
      }
      p.min_branch_mm =
          non_negative(*t, "centreline.min_branch_mm", "min_branch_mm", p.min_branch_mm);
      p.start_mm = numbers<3>(*t, "centreline.start_mm", "start_mm");
      p.end_margin_radii =
          non_negative(*t, "centreline.end_margin_radii", "end_margin_radii", p.end_margin_radii);
      p.junction_margin_radii = non_negative(*t, "centreline.junction_margin_radii",
                                             "junction_margin_radii", p.junction_margin_radii);
      if (const toml::node* n = t->get("orthogonal")) {
        if (!n->is_boolean()) fail(n, *t, "centreline.orthogonal", "expected true or false");
        p.orthogonal = n->value<bool>().value_or(true);
      }
    }
    if (const toml::table* t = table(root, "cluster")) {
      only_keys(
          *t, "cluster",
          {"cases_per_task", "max_running", "cpus_per_task", "mem_mb", "time_limit", "partition"});
      p.cases_per_task = static_cast<int>(
          integer(*t, "cluster.cases_per_task", "cases_per_task", p.cases_per_task, 1, 100000));
      p.max_running = static_cast<int>(
          integer(*t, "cluster.max_running", "max_running", p.max_running, 1, 100000));
      p.cpus_per_task = static_cast<int>(
          integer(*t, "cluster.cpus_per_task", "cpus_per_task", p.cpus_per_task, 1, 1024));
      p.mem_mb = static_cast<int>(integer(*t, "cluster.mem_mb", "mem_mb", p.mem_mb, 1, 1 << 24));
      p.time_limit = string_or(*t, "cluster.time_limit", "time_limit", p.time_limit);
      // Slurm's forms: minutes, [days-]hours:minutes:seconds and their shorter variants.
      static const std::regex time_form(
          R"(^(\d+|\d+:\d{1,2}|\d+:\d{1,2}:\d{1,2}|\d+-\d+|\d+-\d+:\d{1,2}|\d+-\d+:\d{1,2}:\d{1,2})$)");
      if (!std::regex_match(p.time_limit, time_form)) {
        fail(t->get("time_limit"), *t, "cluster.time_limit",
             "expected a Slurm time: MM, HH:MM:SS or D-HH:MM:SS");
      }
      p.partition = string_or(*t, "cluster.partition", "partition", p.partition);
      static const std::regex name_form(R"(^[A-Za-z0-9_.,-]*$)");
      if (!std::regex_match(p.partition, name_form)) {
        fail(t->get("partition"), *t, "cluster.partition", "expected a partition name");
      }
    }
    return p;
  }

 private:
  [[noreturn]] void fail(const toml::node* node, const toml::node& parent, const std::string& key,
                         const std::string& reason) const {
    const toml::source_region& where = node != nullptr ? node->source() : parent.source();
    throw std::runtime_error(name_ + ": line " + std::to_string(where.begin.line) + ": key '" +
                             key + "': " + reason);
  }

  void only_keys(const toml::table& t, const std::string& path,
                 std::initializer_list<std::string_view> allowed) const {
    for (auto&& [key, value] : t) {
      bool ok = false;
      std::string list;
      for (std::string_view a : allowed) {
        ok = ok || key.str() == a;
        list += (list.empty() ? "" : ", ") + std::string(a);
      }
      if (!ok) {
        const std::string full =
            path.empty() ? std::string(key.str()) : path + "." + std::string(key.str());
        fail(&value, t, full, "unknown key (expected one of: " + list + ")");
      }
    }
  }

  const toml::table* table(const toml::table& t, std::string_view key) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return nullptr;
    if (!n->is_table())
      fail(n, t, std::string(key), "expected a table ([" + std::string(key) + "])");
    return n->as_table();
  }

  double number(const toml::table& t, const std::string& full, std::string_view key,
                double fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_number()) fail(n, t, full, "expected a number");
    const double v = n->value<double>().value_or(fallback);
    if (!std::isfinite(v)) fail(n, t, full, "expected a finite number");
    return v;
  }

  double non_negative(const toml::table& t, const std::string& full, std::string_view key,
                      double fallback) const {
    const double v = number(t, full, key, fallback);
    if (v < 0.0) fail(t.get(key), t, full, "must not be negative");
    return v;
  }

  long long integer(const toml::table& t, const std::string& full, std::string_view key,
                    long long fallback, long long lo, long long hi) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_integer()) fail(n, t, full, "expected an integer");
    const long long v = n->value<long long>().value_or(fallback);
    if (v < lo || v > hi) {
      fail(n, t, full,
           "expected an integer from " + std::to_string(lo) + " to " + std::to_string(hi));
    }
    return v;
  }

  std::string string_or(const toml::table& t, const std::string& full, std::string_view key,
                        const std::string& fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_string()) fail(n, t, full, "expected a string");
    return n->value<std::string>().value_or(fallback);
  }

  template <std::size_t N>
  std::optional<std::array<double, N>> numbers(const toml::table& t, const std::string& full,
                                               std::string_view key) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return std::nullopt;
    const toml::array* a = n->as_array();
    if (a == nullptr || a->size() != N) {
      fail(n, t, full, "expected " + std::to_string(N) + " numbers");
    }
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) {
      const toml::node* e = a->get(i);
      if (!e->is_number() || !std::isfinite(e->value<double>().value_or(NAN))) {
        fail(e, t, full + "[" + std::to_string(i) + "]", "expected a finite number");
      }
      out[i] = e->value<double>().value_or(0.0);
    }
    return out;
  }

  std::string name_;
};

nlohmann::json optional_point(const std::optional<std::array<double, 3>>& p) {
  return p ? nlohmann::json(*p) : nlohmann::json(nullptr);
}

}  // namespace

std::array<double, 2> PipelinePlan::threshold_range() const {
  if (method == "window") return {range[0] - 0.5 * range[1], range[0] + 0.5 * range[1]};
  return range;
}

PipelinePlan read_plan(const std::filesystem::path& file) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) {
    throw std::runtime_error(file.string() + ": " +
                             (std::filesystem::exists(file, ec) ? "not a regular file"
                                                                : "no such file"));
  }
  toml::table root;
  try {
    root = toml::parse_file(file.string());
  } catch (const toml::parse_error& e) {
    throw std::runtime_error(file.string() + ": line " + std::to_string(e.source().begin.line) +
                             ": " + std::string(e.description()));
  }
  return PlanReader(file.string()).read(root);
}

nlohmann::json plan_processing_json(const PipelinePlan& p) {
  nlohmann::json seg = {{"method", p.method},
                        {"seed_mm", optional_point(p.seed_mm)},
                        {"connectivity", p.connectivity}};
  if (p.method == "label") {
    seg["label"] = p.label;
  } else {
    seg["range"] = p.range;
    seg["threshold_range"] = p.threshold_range();
  }
  return {{"segmentation", seg},
          {"surface", {{"smooth", p.smooth}, {"decimate", p.decimate}}},
          {"centreline",
           {{"section_step_mm", p.section_step_mm},
            {"min_branch_mm", p.min_branch_mm},
            {"start_mm", optional_point(p.start_mm)},
            {"end_margin_radii", p.end_margin_radii},
            {"junction_margin_radii", p.junction_margin_radii},
            {"orthogonal", p.orthogonal}}}};
}

nlohmann::json plan_cluster_json(const PipelinePlan& p) {
  return {{"cases_per_task", p.cases_per_task}, {"max_running", p.max_running},
          {"cpus_per_task", p.cpus_per_task},   {"mem_mb", p.mem_mb},
          {"time_limit", p.time_limit},         {"partition", p.partition}};
}

}  // namespace bisturi::cli
