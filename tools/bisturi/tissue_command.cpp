#include "tissue_command.h"

#include "number_checks.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <iostream>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <vector>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/sim/integrator.h"
#include "bisturi/sim/tissue.h"
#include "progress_line.h"
#include "tissue_indent_shapes.h"

namespace bisturi::cli {

namespace {

using Curve = IndentCurve;

Curve indent(const TissueIndentOptions& o, const sim::ElasticMaterial& elastic) {
  const bool sphere = o.shape == "sphere";
  const double size_mm = o.size_mm;
  PolygonMesh mesh;
  if (sphere) {
    mesh = sphere_mesh(size_mm, o.vertices);
  } else {
    const auto n =
        static_cast<std::size_t>(std::max(2.0, std::round(std::sqrt(double(o.vertices) / 6.0))));
    mesh = block_mesh(size_mm, n);
  }
  sim::Material material = sim::calibrate_surface(elastic);
  material.drag_per_s = 50.0;  // settles each depth quickly; the static force does not depend on it
  sim::SoftBody body(build_oriented_manifold(mesh), material);
  Curve curve;
  curve.vertices = body.positions().size();
  curve.structural_N_per_m = material.structural_N_per_m;
  curve.bulk_modulus_Pa = material.bulk_modulus_Pa;
  // The rigid plane: the bottom held (the sphere's cap within a fiftieth of its size).
  double zmin = 1e300, zmax = -1e300;
  glm::dvec3 lo(1e300), hi(-1e300);
  for (const glm::dvec3& p : body.positions()) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  zmin = lo.z;
  zmax = hi.z;
  const double hold = sphere ? 0.02 * (zmax - zmin) : 1e-6 * (zmax - zmin);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    const VertexId v(i);
    if (body.mesh().alive(v) && body.position(v).z < zmin + hold) body.set_anchored(v, true);
  }
  const double centre_x = 0.5 * (lo.x + hi.x), centre_y = 0.5 * (lo.y + hi.y);
  const double r = o.probe_radius_mm * 1e-3;
  // The probe's contact: a penalty on each vertex inside the probe, stiff against the tissue.
  const double k_contact = 50.0 * material.structural_N_per_m;
  sim::IntegratorOptions options;
  options.dt_s = o.dt_s;
  options.gravity_m_s2 = glm::dvec3(0.0);
  options.sleeping = false;
  sim::ImplicitIntegrator integrator;
  std::vector<sim::SimEvent> events;
  const double e_star =
      elastic.youngs_modulus_kPa * 1e3 / (1.0 - elastic.poisson_ratio * elastic.poisson_ratio);
  const double body_r = sphere ? size_mm * 1e-3 : INFINITY;
  ProgressLine progress(!o.json);
  const int total = o.points * o.settle_steps;
  for (int p = 1; p <= o.points; ++p) {
    const double depth = o.depth_mm * 1e-3 * double(p) / double(o.points);
    const glm::dvec3 c(centre_x, centre_y, zmax + r - depth);
    // The probe's force: the mean over the last quarter of the steps held (a vertex at the
    // probe's surface flickers in and out of it from step to step).
    const int from = o.settle_steps - std::max(1, o.settle_steps / 4);
    double force_sum = 0.0;
    for (int s = 0; s < o.settle_steps; ++s) {
      double force = 0.0;
      const auto& x = body.positions();
      for (std::uint32_t i = 0; i < x.size(); ++i) {
        const glm::dvec3 d = x[i] - c;
        const double len = glm::length(d);
        if (len >= r || len <= 0.0 || body.anchored(VertexId(i))) continue;
        const glm::dvec3 n = d / len;
        body.add_contact(VertexId(i), n, r - len, k_contact);
        force -= k_contact * (r - len) * n.z;
      }
      if (s >= from) force_sum += force;
      integrator.step(body, options, events);
      progress.show("indent", std::size_t((p - 1) * o.settle_steps + s), std::size_t(total));
    }
    curve.depth_mm.push_back(depth * 1e3);
    curve.force_N.push_back(force_sum / double(o.settle_steps - from));
    curve.hertz_N.push_back(hertz_force(depth, e_star, r, body_r, sphere));
  }
  curve.rollbacks = events.size();
  return curve;
}

/// The slope of log force against log depth over the shallow depths (those within a tenth of
/// the deepest, and at least the first two): 1.5 for Hertz contact.
double small_depth_exponent(const Curve& c) {
  std::vector<std::size_t> use;
  for (std::size_t i = 0; i < c.depth_mm.size(); ++i)
    if (c.force_N[i] > 0.0 && c.depth_mm[i] > 0.0) use.push_back(i);
  if (use.size() < 2) return 0.0;
  std::size_t n = 2;
  while (n < use.size() && c.depth_mm[use[n]] <= 0.1 * c.depth_mm.back() * 1.0000001)
    ++n;
  double sx = 0, sy = 0, sxx = 0, sxy = 0;
  for (std::size_t k = 0; k < n; ++k) {
    const double x = std::log(c.depth_mm[use[k]]), y = std::log(c.force_N[use[k]]);
    sx += x;
    sy += y;
    sxx += x * x;
    sxy += x * y;
  }
  const double dn = double(n);
  return (dn * sxy - sx * sy) / (dn * sxx - sx * sx);
}

}  // namespace

void add_tissue_command(CLI::App& app, TissueIndentOptions& o,
                        int (*&run)(const TissueIndentOptions&)) {
  CLI::App* tissue = app.add_subcommand("tissue", "check the simulated tissue against a solid");
  tissue->require_subcommand(1);
  CLI::App* cmd = tissue->add_subcommand(
      "indent",
      "press a rigid sphere into a simulated sphere or block (quasi-static) and print the "
      "force-depth curve beside Hertz contact for the material's modulus");
  cmd->add_option("--shape", o.shape,
                  "sphere (radius S on a rigid plane) or block (cube of side S)")
      ->check(CLI::IsMember({"sphere", "block"}));
  cmd->add_option("--size-mm", o.size_mm, "S: the sphere's radius or the block's side (mm)")
      ->check(kPositive);
  auto* material = cmd->add_option("--material", o.material,
                                   "a tissue preset: liver, kidney, spleen, vessel-wall, fat");
  auto* youngs =
      cmd->add_option("--youngs-kPa", o.youngs_kPa, "Young's modulus (kPa)")->check(kPositive);
  material->excludes(youngs);
  cmd->add_option("--poisson", o.poisson,
                  "Poisson's ratio in [0, 0.5) (default: the preset's, 0.45)");
  cmd->add_option("--probe-radius-mm", o.probe_radius_mm, "R: the rigid probe's radius (mm)")
      ->check(kPositive);
  cmd->add_option("--depth-mm", o.depth_mm, "D: the deepest indentation (mm)")->check(kPositive);
  cmd->add_option("--model", o.model,
                  "volume (hexahedral finite elements under the surface, the default) or "
                  "surface (the spring membrane)")
      ->check(CLI::IsMember({"volume", "surface"}));
  cmd->add_option("--cell-mm", o.cell_mm,
                  "volume: the finest cell, at the probe (mm; default: the probe's radius / 8)")
      ->check(kPositive);
  cmd->add_option("--lattice", o.lattice,
                  "volume: graded (rectilinear, growing away from the probe; the default) or "
                  "two-level (cells of four times the finest, split in 64 about the probe)")
      ->check(CLI::IsMember({"graded", "two-level"}));
  cmd->add_option("--vertices", o.vertices,
                  "about this many surface vertices (default 2000; volume: 20000)")
      ->check(CLI::Range(std::size_t{50}, std::size_t{2000000}))
      ->each([&o](const std::string&) { o.vertices_given = true; });
  cmd->add_option("--dt-s", o.dt_s, "the integrator's step (s, default 1e-3)")
      ->check(CLI::Range(1e-6, 0.1));
  cmd->add_option("--points", o.points, "depths sampled up to D (default 10)")
      ->check(CLI::Range(1, 1000));
  cmd->add_option("--settle-steps", o.settle_steps, "steps held at each depth (default 400)")
      ->check(CLI::Range(1, 1000000));
  cmd->add_flag("--json", o.json,
                "write one JSON object with arrays depth_mm, force_N and hertz_N on stdout");
  cmd->callback([&run] { run = run_tissue_indent; });
}

int run_tissue_indent(const TissueIndentOptions& o) {
  sim::ElasticMaterial elastic;
  std::string name = "custom";
  if (!o.material.empty()) {
    elastic = sim::tissue_preset(o.material).material;
    name = o.material;
  } else if (o.youngs_kPa > 0.0) {
    elastic.youngs_modulus_kPa = o.youngs_kPa;
  } else {
    throw std::invalid_argument("tissue indent: give --material NAME or --youngs-kPa E");
  }
  if (o.poisson >= 0.0) elastic.poisson_ratio = o.poisson;
  sim::check_elastic(elastic);
  const Curve c = o.model == "volume"
                      ? indent_volume(o, elastic.youngs_modulus_kPa, elastic.poisson_ratio)
                      : indent(o, elastic);
  std::vector<double> error;
  for (std::size_t i = 0; i < c.force_N.size(); ++i)
    error.push_back(c.hertz_N[i] > 0.0 ? c.force_N[i] / c.hertz_N[i] - 1.0 : 0.0);
  double worst = 0.0;
  for (const double e : error)
    worst = std::max(worst, std::abs(e));
  if (o.json) {
    nlohmann::json j = {{"shape", o.shape},
                        {"size_mm", o.size_mm},
                        {"material", name},
                        {"youngs_modulus_kPa", elastic.youngs_modulus_kPa},
                        {"poisson_ratio", elastic.poisson_ratio},
                        {"probe_radius_mm", o.probe_radius_mm},
                        {"model", o.model},
                        {"vertices", c.vertices},
                        {"depth_mm", c.depth_mm},
                        {"force_N", c.force_N},
                        {"hertz_N", c.hertz_N},
                        {"relative_error", error},
                        {"worst_relative_error", worst},
                        {"small_depth_exponent", small_depth_exponent(c)}};
    if (o.model == "volume") {
      j["cells"] = c.cells;
      j["nodes"] = c.nodes;
      j["held_nodes"] = c.held_nodes;
      j["finest_cell_mm"] = c.finest_cell_mm;
      j["build_s"] = c.build_s;
      j["solve_s"] = c.solve_s;
      j["newton_iterations"] = c.newton_iterations;
      j["cg_iterations"] = c.cg_iterations;
      j["converged"] = c.converged;
    } else {
      j["dt_s"] = o.dt_s;
      j["structural_N_per_m"] = c.structural_N_per_m;
      j["bulk_modulus_Pa"] = c.bulk_modulus_Pa;
      j["rollbacks"] = c.rollbacks;
    }
    std::cout << j.dump(2) << "\n";
    return 0;
  }
  std::printf("%s of %.3g mm, %s (E = %.4g kPa, nu = %.3g), probe radius %.3g mm, %zu vertices\n",
              o.shape.c_str(), o.size_mm, name.c_str(), elastic.youngs_modulus_kPa,
              elastic.poisson_ratio, o.probe_radius_mm, c.vertices);
  if (o.model == "volume") {
    std::printf(
        "volume: %zu hexahedra, %zu nodes (%zu held), finest cell %.3g mm; built in %.2f s, "
        "solved in %.2f s (%d Newton steps, %ld CG iterations)%s\n",
        c.cells, c.nodes, c.held_nodes, c.finest_cell_mm, c.build_s, c.solve_s, c.newton_iterations,
        c.cg_iterations, c.converged ? "" : ", NOT converged");
  } else {
    std::printf("surface: dt %.3g s, calibrated structural %.4g N/m, bulk modulus %.4g Pa\n",
                o.dt_s, c.structural_N_per_m, c.bulk_modulus_Pa);
  }
  std::printf("%10s %14s %14s %10s\n", "depth_mm", "force_N", "hertz_N", "error");
  for (std::size_t i = 0; i < c.force_N.size(); ++i) {
    std::printf("%10.3f %14.6g %14.6g %9.1f%%\n", c.depth_mm[i], c.force_N[i], c.hertz_N[i],
                100.0 * error[i]);
  }
  std::printf("worst relative error %.1f %% (Hertz); small-depth exponent %.3f (Hertz: 1.5)%s\n",
              100.0 * worst, small_depth_exponent(c),
              c.rollbacks > 0 ? ", with guard rollbacks" : "");
  return 0;
}

}  // namespace bisturi::cli
