// Scene files: TOML read with toml++, checked key by key so that every problem names the file,
// the line and the key (a typo in a key is an error, not a silently ignored setting).

#include <toml++/toml.h>

#include <cmath>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>

#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/sim/errors.h"
#include "bisturi/sim/tissue.h"
#include "default_scene_toml.h"
#include "embedded_data.h"

namespace bisturi::runtime {

namespace {

class SceneReader {
 public:
  SceneReader(std::string name, std::filesystem::path base_dir, bool embedded_files = false)
      : name_(std::move(name)), base_dir_(std::move(base_dir)), embedded_files_(embedded_files) {}

  SceneDescription read(const toml::table& root) {
    SceneDescription scene;
    only_keys(root, "",
              {"name", "duration_s", "rates", "simulation", "physiology", "headset", "solids",
               "devices", "instruments", "procedure"});
    scene.name = string_or(root, "", "name", scene.name);
    scene.duration_s = positive(root, "", "duration_s", scene.duration_s);
    if (const toml::table* t = table_at(root, "", "rates")) {
      only_keys(*t, "rates", {"haptic_hz", "display_hz"});
      scene.rates.haptic_hz = positive(*t, "rates", "haptic_hz", scene.rates.haptic_hz);
      scene.rates.display_hz = positive(*t, "rates", "display_hz", scene.rates.display_hz);
    }
    if (const toml::table* t = table_at(root, "", "simulation")) {
      only_keys(*t, "simulation",
                {"far_field_interval", "stale_margin_ticks", "continuous_collision"});
      scene.simulation.continuous_collision =
          boolean(*t, "simulation", "continuous_collision", scene.simulation.continuous_collision);
      scene.simulation.far_field_interval = static_cast<int>(integer(
          *t, "simulation", "far_field_interval", scene.simulation.far_field_interval, 1, 256));
      scene.simulation.stale_margin_ticks = static_cast<int>(integer(
          *t, "simulation", "stale_margin_ticks", scene.simulation.stale_margin_ticks, 1, 1000));
    }
    if (const toml::table* t = table_at(root, "", "physiology")) {
      only_keys(*t, "physiology",
                {"heart_rate_bpm", "breathing_period_s", "blood_density_kg_per_m3",
                 "blood_viscosity", "blood_max_particles"});
      PhysiologyDescription& ph = scene.physiology;
      ph.blood_density_kg_per_m3 =
          positive(*t, "physiology", "blood_density_kg_per_m3", ph.blood_density_kg_per_m3);
      ph.blood_viscosity = number(*t, "physiology", "blood_viscosity", ph.blood_viscosity);
      if (!(ph.blood_viscosity >= 0.0 && ph.blood_viscosity <= 1.0))
        fail(t->get("blood_viscosity"), *t, "physiology.blood_viscosity", "must be in [0, 1]");
      ph.blood_max_particles = static_cast<int>(
          integer(*t, "physiology", "blood_max_particles", ph.blood_max_particles, 0, 100000));
      scene.physiology.breathing_period_s =
          positive(*t, "physiology", "breathing_period_s", scene.physiology.breathing_period_s);
      if (scene.physiology.breathing_period_s < 1.0 || scene.physiology.breathing_period_s > 60.0) {
        fail(t->get("breathing_period_s"), *t, "physiology.breathing_period_s",
             "must be between 1 and 60 seconds");
      }
      scene.physiology.heart_rate_bpm =
          positive(*t, "physiology", "heart_rate_bpm", scene.physiology.heart_rate_bpm);
      if (scene.physiology.heart_rate_bpm < 20.0 || scene.physiology.heart_rate_bpm > 300.0) {
        fail(t->get("heart_rate_bpm"), *t, "physiology.heart_rate_bpm",
             "must be between 20 and 300 beats per minute");
      }
    }
    if (const toml::table* t = table_at(root, "", "headset")) read_headset(*t, scene.headset);
    for_each_table(root, "solids", [&](const toml::table& t, const std::string& path) {
      scene.solids.push_back(read_solid(t, path));
    });
    for_each_table(root, "devices", [&](const toml::table& t, const std::string& path) {
      scene.devices.push_back(read_device(t, path));
    });
    for_each_table(root, "instruments", [&](const toml::table& t, const std::string& path) {
      InstrumentDescription in = read_instrument(t, path);
      bool found = false;
      for (const DeviceDescription& d : scene.devices)
        found = found || d.name == in.device;
      if (!found)
        fail(t["device"].node(), t, path + ".device", "no device named '" + in.device + "'");
      scene.instruments.push_back(std::move(in));
    });
    if (const toml::table* t = table_at(root, "", "procedure"))
      scene.procedure = read_procedure(*t);
    return scene;
  }

 private:
  [[noreturn]] void fail(const toml::node* node, const toml::node& parent, const std::string& key,
                         const std::string& reason) const {
    const toml::source_region& where = node != nullptr ? node->source() : parent.source();
    throw SceneFileError(name_ + ": line " + std::to_string(where.begin.line) + ": key '" + key +
                         "': " + reason);
  }

  static std::string join(const std::string& path, std::string_view key) {
    return path.empty() ? std::string(key) : path + "." + std::string(key);
  }

  void only_keys(const toml::table& t, const std::string& path,
                 std::initializer_list<std::string_view> allowed) const {
    for (auto&& [key, value] : t) {
      bool ok = false;
      for (std::string_view a : allowed)
        ok = ok || key.str() == a;
      if (!ok) {
        std::string list;
        for (std::string_view a : allowed)
          list += (list.empty() ? "" : ", ") + std::string(a);
        fail(&value, t, join(path, key.str()), "unknown key (expected one of: " + list + ")");
      }
    }
  }

  const toml::table* table_at(const toml::table& t, const std::string& path,
                              std::string_view key) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return nullptr;
    if (!n->is_table()) fail(n, t, join(path, key), "expected a table");
    return n->as_table();
  }

  template <class Fn>
  void for_each_table(const toml::table& t, std::string_view key, Fn&& fn) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return;
    const toml::array* a = n->as_array();
    if (a == nullptr || !a->is_array_of_tables()) {
      fail(n, t, std::string(key), "expected an array of tables ([[" + std::string(key) + "]])");
    }
    for (std::size_t i = 0; i < a->size(); ++i) {
      fn(*a->get(i)->as_table(), std::string(key) + "[" + std::to_string(i) + "]");
    }
  }

  double number(const toml::table& t, const std::string& path, std::string_view key,
                double fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_number()) fail(n, t, join(path, key), "expected a number");
    const double v = n->value<double>().value_or(fallback);
    if (!std::isfinite(v)) fail(n, t, join(path, key), "expected a finite number");
    return v;
  }

  double positive(const toml::table& t, const std::string& path, std::string_view key,
                  double fallback) const {
    const double v = number(t, path, key, fallback);
    if (!(v > 0.0)) fail(t.get(key), t, join(path, key), "must be greater than 0");
    return v;
  }

  std::int64_t integer(const toml::table& t, const std::string& path, std::string_view key,
                       std::int64_t fallback, std::int64_t lo, std::int64_t hi) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_integer()) fail(n, t, join(path, key), "expected an integer");
    const std::int64_t v = *n->value<std::int64_t>();
    if (v < lo || v > hi) {
      fail(n, t, join(path, key),
           "must be between " + std::to_string(lo) + " and " + std::to_string(hi));
    }
    return v;
  }

  bool boolean(const toml::table& t, const std::string& path, std::string_view key,
               bool fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_boolean()) fail(n, t, join(path, key), "expected true or false");
    return *n->value<bool>();
  }

  /// [solids.material]: a preset and/or elastic parameters, calibrated into the surface model's
  /// springs and volume term; stiffness_N_per_m by hand is the expert override.
  void read_material(const toml::table& m, const std::string& path,
                     MaterialDescription& out) const {
    const std::string mp = path + ".material";
    only_keys(m, mp,
              {"preset", "youngs_modulus_kPa", "poisson_ratio", "retardation_time_s",
               "stiffness_N_per_m", "damping_N_s_per_m", "density_kg_per_m3", "colour"});
    sim::ElasticMaterial elastic;
    bool any_elastic = false;
    if (m.contains("preset")) {
      out.preset = string_or(m, mp, "preset", "");
      try {
        elastic = sim::tissue_preset(out.preset).material;
      } catch (const sim::SimInputError& e) {
        fail(m.get("preset"), m, mp + ".preset", e.what());
      }
      any_elastic = true;
    }
    for (const char* key : {"youngs_modulus_kPa", "poisson_ratio", "retardation_time_s"})
      any_elastic = any_elastic || m.contains(key);
    elastic.youngs_modulus_kPa = number(m, mp, "youngs_modulus_kPa", elastic.youngs_modulus_kPa);
    elastic.poisson_ratio = number(m, mp, "poisson_ratio", elastic.poisson_ratio);
    elastic.retardation_time_s = number(m, mp, "retardation_time_s", elastic.retardation_time_s);
    elastic.density_kg_per_m3 = positive(m, mp, "density_kg_per_m3", elastic.density_kg_per_m3);
    out.density_kg_per_m3 = any_elastic
                                ? elastic.density_kg_per_m3
                                : positive(m, mp, "density_kg_per_m3", out.density_kg_per_m3);
    if (any_elastic) {
      sim::Material calibrated;
      try {
        calibrated = sim::calibrate_surface(elastic);
      } catch (const sim::SimInputError& e) {
        fail(nullptr, m, mp, e.what());
      }
      out.elastic = true;
      out.youngs_modulus_kPa = elastic.youngs_modulus_kPa;
      out.poisson_ratio = elastic.poisson_ratio;
      out.retardation_time_s = elastic.retardation_time_s;
      out.stiffness_N_per_m = calibrated.structural_N_per_m;
      out.damping_N_s_per_m = calibrated.spring_damping_N_s_per_m;
      out.bulk_modulus_Pa = calibrated.bulk_modulus_Pa;
    }
    if (m.contains("stiffness_N_per_m")) {
      out.stiffness_override = true;
      out.stiffness_N_per_m = positive(m, mp, "stiffness_N_per_m", out.stiffness_N_per_m);
    }
    out.damping_N_s_per_m = number(m, mp, "damping_N_s_per_m", out.damping_N_s_per_m);
    if (out.damping_N_s_per_m < 0.0) {
      fail(m.get("damping_N_s_per_m"), m, mp + ".damping_N_s_per_m", "must not be negative");
    }
    out.colour = numbers<3>(m, mp, "colour", out.colour);
  }

  std::string string_or(const toml::table& t, const std::string& path, std::string_view key,
                        const std::string& fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    if (!n->is_string()) fail(n, t, join(path, key), "expected a string");
    return *n->value<std::string>();
  }

  template <std::size_t N>
  std::array<double, N> numbers(const toml::table& t, const std::string& path, std::string_view key,
                                const std::array<double, N>& fallback) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    const toml::array* a = n->as_array();
    if (a == nullptr || a->size() != N) {
      fail(n, t, join(path, key), "expected an array of " + std::to_string(N) + " numbers");
    }
    std::array<double, N> out{};
    for (std::size_t i = 0; i < N; ++i) {
      const toml::node* e = a->get(i);
      if (!e->is_number() || !std::isfinite(e->value<double>().value_or(NAN))) {
        fail(e, t, join(path, key) + "[" + std::to_string(i) + "]", "expected a finite number");
      }
      out[i] = *e->value<double>();
    }
    return out;
  }

  template <class E>
  E choice(const toml::table& t, const std::string& path, std::string_view key, E fallback,
           std::initializer_list<std::pair<std::string_view, E>> options) const {
    const toml::node* n = t.get(key);
    if (n == nullptr) return fallback;
    const std::string v = string_or(t, path, key, "");
    std::string list;
    for (const auto& [name, value] : options) {
      if (v == name) return value;
      list += (list.empty() ? "" : ", ") + std::string(name);
    }
    fail(n, t, join(path, key), "'" + v + "' is not one of: " + list);
  }

  std::filesystem::path file_path(const toml::table& t, const std::string& path,
                                  std::string_view key, bool* embedded = nullptr) const {
    std::filesystem::path p = string_or(t, path, key, "");
    if (p.empty()) fail(t.get(key), t, join(path, key), "expected a file name");
    const std::filesystem::path named = p;
    if (p.is_relative() && !base_dir_.empty()) p = base_dir_ / p;
    // The embedded default scene names the files embedded with it (config/data/...); a scene
    // file too when no such file is beside it (the default scene printed and edited elsewhere).
    if (embedded != nullptr && named.is_relative() &&
        (embedded_files_ || !std::filesystem::exists(p)) && embedded_file(named.generic_string())) {
      *embedded = true;
      return named;
    }
    if (!std::filesystem::exists(p))
      fail(t.get(key), t, join(path, key), "no such file: " + p.string());
    return p;
  }

  void read_headset(const toml::table& t, HeadsetDescription& h) const {
    only_keys(t, "headset",
              {"ipd_mm", "fov_deg", "eye_width", "eye_height", "refresh_hz", "reference_space",
               "field_centre_mm", "field_height_m", "field_distance_m"});
    h.ipd_mm = positive(t, "headset", "ipd_mm", h.ipd_mm);
    h.fov_deg = numbers<4>(t, "headset", "fov_deg", h.fov_deg);
    for (std::size_t i = 0; i < 4; ++i) {
      if (!(h.fov_deg[i] > 0.0 && h.fov_deg[i] < 89.0)) {
        fail(t.get("fov_deg"), t, "headset.fov_deg[" + std::to_string(i) + "]",
             "each half-angle must be between 0 and 89 degrees");
      }
    }
    h.eye_width = static_cast<int>(integer(t, "headset", "eye_width", h.eye_width, 16, 8192));
    h.eye_height = static_cast<int>(integer(t, "headset", "eye_height", h.eye_height, 16, 8192));
    h.refresh_hz = positive(t, "headset", "refresh_hz", h.refresh_hz);
    // Where the scene sits in an OpenXR headset's space.
    h.stage_space =
        choice(t, "headset", "reference_space", h.stage_space, {{"local", false}, {"stage", true}});
    if (t.get("field_centre_mm") != nullptr) {
      h.field_centre_mm = numbers<3>(t, "headset", "field_centre_mm", {});
    }
    if (t.get("field_height_m") != nullptr) {
      h.field_height_m = number(t, "headset", "field_height_m", 0.0);
    }
    h.field_distance_m = number(t, "headset", "field_distance_m", h.field_distance_m);
  }

  /// Three integers in [lo, hi] at `key` (which must be there).
  std::array<std::int64_t, 3> integers3(const toml::table& t, const std::string& path,
                                        const std::string& key, std::int64_t lo,
                                        std::int64_t hi) const {
    std::array<std::int64_t, 3> out{};
    const toml::node* n = t.get(key);
    const toml::array* a = n->as_array();
    if (a == nullptr || a->size() != 3) fail(n, t, path + "." + key, "expected 3 integers");
    for (std::size_t i = 0; i < 3; ++i) {
      const auto v = a->get(i)->value<std::int64_t>();
      if (!a->get(i)->is_integer() || !v || *v < lo || *v > hi) {
        fail(a->get(i), t, path + "." + key + "[" + std::to_string(i) + "]",
             "expected an integer between " + std::to_string(lo) + " and " + std::to_string(hi));
      }
      out[i] = *v;
    }
    return out;
  }

  /// A label map's downsampling: 3 integers in [1, 64].
  std::array<int, 3> downsample(const toml::table& t, const std::string& path) const {
    const std::array<std::int64_t, 3> v = integers3(t, path, "downsample", 1, 64);
    return {static_cast<int>(v[0]), static_cast<int>(v[1]), static_cast<int>(v[2])};
  }

  SolidDescription read_solid(const toml::table& t, const std::string& path) const {
    only_keys(t, path,
              {"name",    "mesh",      "volume",     "phantom",    "dims",          "spacing_mm",
               "a_mm",    "b_mm",      "iso",        "label",      "downsample",    "decimate",
               "smooth",  "offset_mm", "material",   "anchors",    "simulate",      "model",
               "cell_mm", "refine",    "supported",  "pulse_mmHg", "pressure_mmHg", "breathing_mm",
               "drawn",   "inner",     "tension_Pa", "cut_refine"});
    SolidDescription s;
    s.name = string_or(t, path, "name", path);
    const int sources = (t.contains("mesh") ? 1 : 0) + (t.contains("volume") ? 1 : 0) +
                        (t.contains("phantom") ? 1 : 0);
    if (sources != 1) {
      fail(nullptr, t, path, "give exactly one of 'mesh', 'volume' or 'phantom'");
    }
    if (t.contains("mesh")) {
      s.source = SolidDescription::Source::Mesh;
      s.path = file_path(t, path, "mesh");
    } else if (t.contains("volume")) {
      s.source = SolidDescription::Source::Volume;
      s.path = file_path(t, path, "volume", &s.embedded);
    } else {
      s.source = SolidDescription::Source::Phantom;
      s.phantom = string_or(t, path, "phantom", s.phantom);
    }
    if (t.contains("dims")) s.dims = integers3(t, path, "dims", 2, 1024);
    s.spacing_mm = positive(t, path, "spacing_mm", s.spacing_mm);
    s.a_mm = number(t, path, "a_mm", s.a_mm);
    s.b_mm = number(t, path, "b_mm", s.b_mm);
    s.iso = number(t, path, "iso", s.iso);
    if (t.contains("label")) {
      s.label = static_cast<std::uint32_t>(integer(t, path, "label", 1, 0, 0xffffff));
    }
    if (t.contains("downsample")) {
      s.downsample = downsample(t, path);
      if (!s.label)
        fail(t.get("downsample"), t, path + ".downsample", "only for a label map (give 'label')");
    }
    s.decimate = number(t, path, "decimate", s.decimate);
    if (!(s.decimate > 0.0 && s.decimate <= 1.0)) {
      fail(t.get("decimate"), t, path + ".decimate", "must be in (0, 1]");
    }
    s.smooth = static_cast<int>(integer(t, path, "smooth", s.smooth, 0, 1000));
    s.offset_mm = numbers<3>(t, path, "offset_mm", s.offset_mm);
    s.simulate = boolean(t, path, "simulate", s.simulate);
    if (const toml::table* m = table_at(t, path, "material")) read_material(*m, path, s.material);
    // Solids are volumes unless their material is springs set by hand (or they do not move):
    // a membrane is for shells, a vessel's wall (docs/sim/tissue.md).
    s.model_given = t.contains("model");
    s.model = s.material.elastic && !s.material.stiffness_override && s.simulate
                  ? SolidDescription::Model::Volume
                  : SolidDescription::Model::Surface;
    s.model = choice(t, path, "model", s.model,
                     {{"surface", SolidDescription::Model::Surface},
                      {"volume", SolidDescription::Model::Volume}});
    s.cell_mm = positive(t, path, "cell_mm", s.cell_mm);
    if (t.contains("cell_mm") && s.model != SolidDescription::Model::Volume) {
      fail(t.get("cell_mm"), t, path + ".cell_mm", "only for model = \"volume\"");
    }
    if (const toml::table* r = table_at(t, path, "refine")) {
      const std::string at = path + ".refine";
      if (s.model != SolidDescription::Model::Volume)
        fail(t.get("refine"), t, at, "only for model = \"volume\"");
      only_keys(*r, at, {"centre_mm", "half_width_mm", "factor", "follow"});
      SolidDescription::Refinement refine;
      refine.centre_mm = numbers<3>(*r, at, "centre_mm", refine.centre_mm);
      if (!r->contains("centre_mm")) fail(t.get("refine"), t, at, "needs centre_mm");
      refine.half_width_mm = positive(*r, at, "half_width_mm", 2.0 * s.cell_mm);
      refine.factor = static_cast<int>(integer(*r, at, "factor", refine.factor, 2, 4));
      refine.follow = boolean(*r, at, "follow", refine.follow);
      s.refine = refine;
    }
    if (const toml::table* d = table_at(t, path, "drawn")) {
      const std::string at = path + ".drawn";
      if (s.model != SolidDescription::Model::Volume)
        fail(t.get("drawn"), t, at, "only for model = \"volume\" (a surface rides on a volume)");
      only_keys(*d, at, {"downsample", "decimate", "smooth"});
      SolidDescription::Drawn drawn;
      if (d->contains("downsample")) {
        drawn.downsample = downsample(*d, at);
        if (!s.label)
          fail(d->get("downsample"), *d, at + ".downsample", "only for a label map (give 'label')");
      }
      drawn.decimate = number(*d, at, "decimate", drawn.decimate);
      if (!(drawn.decimate > 0.0 && drawn.decimate <= 1.0))
        fail(d->get("decimate"), *d, at + ".decimate", "must be in (0, 1]");
      drawn.smooth = static_cast<int>(integer(*d, at, "smooth", drawn.smooth, 0, 1000));
      s.drawn = drawn;
    }
    for_each_table(t, "inner", [&](const toml::table& in, const std::string& sub) {
      const std::string at = path + "." + sub;
      if (s.model != SolidDescription::Model::Volume)
        fail(t.get("inner"), t, at, "only for model = \"volume\" (it rides on the volume)");
      only_keys(in, at,
                {"name", "mesh", "volume", "phantom", "dims", "spacing_mm", "a_mm", "b_mm", "iso",
                 "label", "downsample", "decimate", "smooth", "offset_mm", "colour"});
      toml::table shape = in;
      shape.erase("colour");
      SolidDescription inner = read_solid(shape, at);
      inner.simulate = false;
      inner.model = SolidDescription::Model::Surface;
      inner.material.colour = numbers<3>(in, at, "colour", {0.55, 0.45, 0.25});
      s.inner.push_back(std::move(inner));
    });
    s.supported = boolean(t, path, "supported", s.supported);
    if (t.contains("supported") && s.model != SolidDescription::Model::Volume) {
      fail(t.get("supported"), t, path + ".supported", "only for model = \"volume\"");
    }
    if (t.contains("tension_Pa")) {
      s.tension_Pa = number(t, path, "tension_Pa", 0.0);
      if (s.model != SolidDescription::Model::Volume)
        fail(t.get("tension_Pa"), t, path + ".tension_Pa", "only for model = \"volume\"");
      if (!(s.tension_Pa >= 0.0 && s.tension_Pa <= 1e5))
        fail(t.get("tension_Pa"), t, path + ".tension_Pa", "must be from 0 to 100000 Pa");
    }
    if (t.contains("cut_refine")) {
      s.cut_refine = static_cast<int>(integer(t, path, "cut_refine", s.cut_refine, 1, 4));
      if (s.model != SolidDescription::Model::Volume)
        fail(t.get("cut_refine"), t, path + ".cut_refine", "only for model = \"volume\"");
    }
    if (t.contains("pulse_mmHg")) {
      const std::array<double, 2> p = numbers<2>(t, path, "pulse_mmHg", {0.0, 0.0});
      if (!(p[0] >= 0.0 && p[1] > p[0] && p[1] <= 400.0)) {
        fail(t.get("pulse_mmHg"), t, path + ".pulse_mmHg",
             "expected [diastolic, systolic] with 0 <= diastolic < systolic <= 400 mmHg");
      }
      if (!s.simulate)
        fail(t.get("pulse_mmHg"), t, path + ".pulse_mmHg", "a rigid solid cannot pulse");
      s.pulse_mmHg = p;
    }
    if (t.contains("pressure_mmHg")) {  // a vein's steady pressure: no pulse, only a flow if cut
      if (t.contains("pulse_mmHg"))
        fail(t.get("pressure_mmHg"), t, path + ".pressure_mmHg",
             "give either pulse_mmHg (an artery) or pressure_mmHg (a vein), not both");
      const double p = number(t, path, "pressure_mmHg", 0.0);
      if (!(p > 0.0 && p <= 400.0))
        fail(t.get("pressure_mmHg"), t, path + ".pressure_mmHg", "expected 0 < mmHg <= 400");
      if (!s.simulate)
        fail(t.get("pressure_mmHg"), t, path + ".pressure_mmHg", "a rigid solid has no lumen");
      s.pulse_mmHg = std::array<double, 2>{p, p};
    }
    if (s.model == SolidDescription::Model::Volume && !s.material.elastic) {
      fail(t.get("model"), t, path + ".model",
           "a volume takes its elasticity from the material: give [" + path +
               ".material] a preset or youngs_modulus_kPa");
    }
    for_each_table(t, "anchors", [&](const toml::table& a, const std::string& sub) {
      const std::string ap = path + "." + sub;
      only_keys(a, ap, {"point_mm", "normal", "distance_mm"});
      AnchorDescription anchor;
      anchor.point_mm = numbers<3>(a, ap, "point_mm", anchor.point_mm);
      anchor.normal = numbers<3>(a, ap, "normal", anchor.normal);
      const double len = std::hypot(anchor.normal[0], anchor.normal[1], anchor.normal[2]);
      if (!(len > 0.0)) fail(a.get("normal"), a, ap + ".normal", "must not be zero");
      for (double& c : anchor.normal)
        c /= len;
      anchor.distance_mm = number(a, ap, "distance_mm", anchor.distance_mm);
      s.anchors.push_back(anchor);
    });
    if (t.contains("breathing_mm")) {
      s.breathing_mm = numbers<3>(t, path, "breathing_mm", {0.0, 0.0, 0.0});
      // A spring membrane's anchors never move; a volume's anchored cells can carry the organ.
      if (s.model != SolidDescription::Model::Volume || !s.simulate || s.anchors.empty()) {
        fail(t.get("breathing_mm"), t, path + ".breathing_mm",
             "breathing moves a solid by its anchors: it needs model = \"volume\" and "
             "[[" +
                 path + ".anchors]]");
      }
      if (std::hypot((*s.breathing_mm)[0], (*s.breathing_mm)[1], (*s.breathing_mm)[2]) > 50.0)
        fail(t.get("breathing_mm"), t, path + ".breathing_mm", "more than 50 mm");
    }
    return s;
  }

  ProcedureDescription read_procedure(const toml::table& t) const {
    const std::string p = "procedure";
    only_keys(t, p,
              {"palpate_mm", "palpate_normal", "palpate_depth_mm", "grasp_mm", "grasp_normal",
               "pull_mm", "cut_from_mm", "cut_to_mm", "cut_normal", "cut_depth_mm"});
    ProcedureDescription d;
    for (const char* key : {"palpate_mm", "grasp_mm", "cut_from_mm", "cut_to_mm"}) {
      if (!t.contains(key)) fail(nullptr, t, join(p, key), "missing (a target of the procedure)");
    }
    d.palpate_mm = numbers<3>(t, p, "palpate_mm", d.palpate_mm);
    d.grasp_mm = numbers<3>(t, p, "grasp_mm", d.grasp_mm);
    d.cut_from_mm = numbers<3>(t, p, "cut_from_mm", d.cut_from_mm);
    d.cut_to_mm = numbers<3>(t, p, "cut_to_mm", d.cut_to_mm);
    if (d.cut_from_mm == d.cut_to_mm)
      fail(t.get("cut_to_mm"), t, join(p, "cut_to_mm"), "the cut needs two different ends");
    const auto unit = [&](const char* key, std::array<double, 3> v) {
      v = numbers<3>(t, p, key, v);
      const double len = std::hypot(v[0], v[1], v[2]);
      if (!(len > 0.0)) fail(t.get(key), t, join(p, key), "must not be zero");
      for (double& c : v)
        c /= len;
      return v;
    };
    d.palpate_normal = unit("palpate_normal", d.palpate_normal);
    d.grasp_normal = unit("grasp_normal", d.grasp_normal);
    d.cut_normal = unit("cut_normal", d.cut_normal);
    d.palpate_depth_mm = positive(t, p, "palpate_depth_mm", d.palpate_depth_mm);
    d.pull_mm = positive(t, p, "pull_mm", d.pull_mm);
    d.cut_depth_mm = positive(t, p, "cut_depth_mm", d.cut_depth_mm);
    return d;
  }

  DeviceDescription read_device(const toml::table& t, const std::string& path) const {
    only_keys(t, path,
              {"name", "driver", "role", "simulated", "script", "vendor_id", "product_id", "serial",
               "max_force_N", "device_to_scene_rotation_deg", "device_to_scene_translation_mm"});
    DeviceDescription d;
    d.name = string_or(t, path, "name", path);
    d.driver = string_or(t, path, "driver", d.driver);
    d.role = choice(t, path, "role", d.role,
                    {{"haptic", DeviceDescription::Role::Haptic},
                     {"head-tracker", DeviceDescription::Role::HeadTracker}});
    d.simulated = boolean(t, path, "simulated", d.simulated);
    d.script = string_or(t, path, "script", d.script);
    d.vendor_id = static_cast<std::uint16_t>(integer(t, path, "vendor_id", 0, 0, 0xffff));
    d.product_id = static_cast<std::uint16_t>(integer(t, path, "product_id", 0, 0, 0xffff));
    d.serial = string_or(t, path, "serial", d.serial);
    d.max_force_N = positive(t, path, "max_force_N", d.max_force_N);
    d.device_to_scene_rotation_deg =
        numbers<3>(t, path, "device_to_scene_rotation_deg", d.device_to_scene_rotation_deg);
    for (std::size_t i = 0; i < 3; ++i) {
      if (!(std::abs(d.device_to_scene_rotation_deg[i]) <= 360.0)) {
        fail(t.get("device_to_scene_rotation_deg"), t,
             path + ".device_to_scene_rotation_deg[" + std::to_string(i) + "]",
             "must be an angle between -360 and 360 degrees");
      }
    }
    d.device_to_scene_translation_mm =
        numbers<3>(t, path, "device_to_scene_translation_mm", d.device_to_scene_translation_mm);
    if (d.driver.empty() && d.vendor_id == 0) {
      fail(nullptr, t, path, "give a 'driver' name or a 'vendor_id' and 'product_id'");
    }
    return d;
  }

  InstrumentDescription read_instrument(const toml::table& t, const std::string& path) const {
    only_keys(t, path, {"name", "kind", "device", "radius_mm", "length_mm"});
    InstrumentDescription in;
    in.name = string_or(t, path, "name", path);
    in.kind = choice(t, path, "kind", in.kind,
                     {{"probe", InstrumentDescription::Kind::Probe},
                      {"grasper", InstrumentDescription::Kind::Grasper},
                      {"scalpel", InstrumentDescription::Kind::Scalpel}});
    in.device = string_or(t, path, "device", "");
    if (in.device.empty())
      fail(t.get("device"), t, path + ".device", "name the device that drives it");
    in.radius_mm = positive(t, path, "radius_mm", in.radius_mm);
    in.length_mm = positive(t, path, "length_mm", in.length_mm);
    return in;
  }

  std::string name_;
  std::filesystem::path base_dir_;
  bool embedded_files_ = false;
};

}  // namespace

SceneDescription parse_scene(std::string_view toml_text, const std::string& name_for_errors,
                             const std::filesystem::path& base_dir) {
  toml::table root;
  try {
    root = toml::parse(toml_text, name_for_errors);
  } catch (const toml::parse_error& e) {
    throw SceneFileError(name_for_errors + ": line " + std::to_string(e.source().begin.line) +
                         ": " + std::string(e.description()));
  }
  // The embedded default scene's own text (also as a recording holds it, with no folder) names
  // the files embedded with it; any other scene names files on disk.
  const bool embedded_files = base_dir.empty() && toml_text == default_scene_toml();
  return SceneReader(name_for_errors, base_dir, embedded_files).read(root);
}

SceneDescription read_scene_file(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) throw SceneFileError(file.string() + ": cannot open the scene file");
  std::ostringstream text;
  text << in.rdbuf();
  SceneDescription scene = parse_scene(text.str(), file.string(), file.parent_path());
  scene.file = file;
  return scene;
}

std::string_view default_scene_toml() {
  return kDefaultSceneToml;
}

SceneDescription default_scene() {
  return parse_scene(default_scene_toml(), "default scene (config/liver.toml)");
}

}  // namespace bisturi::runtime
