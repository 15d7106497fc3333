// `bisturi tissue indent --model volume`: the sphere or block as a graded hexahedral lattice
// under its surface (finest at the probe), the surface embedded, the bottom held, and the rigid
// probe pressed to each depth in static equilibrium.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <vector>

#include <glm/geometric.hpp>

#include "bisturi/sim/tissue.h"
#include "bisturi/sim/volume/elastic_volume.h"
#include "progress_line.h"
#include "tissue_command.h"
#include "tissue_indent_shapes.h"

namespace bisturi::cli {

namespace {

double seconds_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

/// Where the probe may touch: every vertex, and near the focus points spread over each triangle
/// no further apart than `spacing` (a regular subdivision), so the contact is sampled finer than
/// the cells however coarse the surface mesh is.
std::vector<glm::dvec3> contact_samples(const std::vector<glm::dvec3>& vertices,
                                        const std::vector<std::array<std::uint32_t, 3>>& triangles,
                                        const glm::dvec3& focus, double reach, double spacing) {
  std::vector<glm::dvec3> out = vertices;
  for (const auto& t : triangles) {
    const glm::dvec3 &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
    if (glm::length((a + b + c) / 3.0 - focus) > reach) continue;
    const double longest = std::max({glm::length(b - a), glm::length(c - b), glm::length(a - c)});
    const int m = static_cast<int>(std::ceil(longest / spacing));
    if (m < 2) continue;
    // The subdivision's points strictly inside the triangle and on its edges' interiors (the
    // corners are vertices already; an edge's points come twice, from both its triangles).
    for (int i = 0; i <= m; ++i) {
      for (int j = 0; i + j <= m; ++j) {
        const int k = m - i - j;
        if ((i == m) || (j == m) || (k == m)) continue;
        out.push_back((double(i) * a + double(j) * b + double(k) * c) / double(m));
      }
    }
  }
  return out;
}

}  // namespace

IndentCurve indent_volume(const TissueIndentOptions& o, double youngs_kPa, double poisson) {
  const auto t0 = std::chrono::steady_clock::now();
  const bool sphere = o.shape == "sphere";
  const std::size_t want_vertices = o.vertices_given ? o.vertices : 20000;
  const PolygonMesh mesh =
      sphere ? sphere_mesh(o.size_mm, want_vertices)
             : block_mesh(o.size_mm, static_cast<std::size_t>(std::max(
                                         2.0, std::round(std::sqrt(double(want_vertices) / 6.0)))));
  // The surface in metres, its polygons as triangles (fans).
  std::vector<glm::dvec3> vertices;
  vertices.reserve(mesh.positions.size());
  for (const auto& p : mesh.positions)
    vertices.emplace_back(p.x * 1e-3, p.y * 1e-3, p.z * 1e-3);
  std::vector<std::array<std::uint32_t, 3>> triangles;
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    for (std::size_t k = 1; k + 1 < face.size(); ++k)
      triangles.push_back({face[0], face[k], face[k + 1]});
  }
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::dvec3& v : vertices) {
    lo = glm::dvec3(std::min(lo.x, v.x), std::min(lo.y, v.y), std::min(lo.z, v.z));
    hi = glm::dvec3(std::max(hi.x, v.x), std::max(hi.y, v.y), std::max(hi.z, v.z));
  }
  const double r = o.probe_radius_mm * 1e-3, depth_max = o.depth_mm * 1e-3;
  const glm::dvec3 top(0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), hi.z);
  // Cells finest over the deepest contact patch (Hertz: a = sqrt(R d), a little wider), and at
  // most a fifth of the solid's size far from it.
  sim::LatticeOptions lattice;
  lattice.finest_m = o.cell_mm > 0.0 ? o.cell_mm * 1e-3 : r / 8.0;
  lattice.focus_m = top;
  lattice.fine_half_width_m = 1.2 * std::sqrt(r * depth_max) + lattice.finest_m;
  lattice.coarsest_m = std::max(lattice.finest_m, 0.2 * (hi.z - lo.z));
  lattice.growth = 1.3;
  sim::ElasticMaterial material;
  material.youngs_modulus_kPa = youngs_kPa;
  material.poisson_ratio = poisson;
  // The sphere stands on a rigid plane through its bottom cap (a fiftieth of its height): the
  // solid is cut there and the cut held, cells next to it a third of the cap's radius.
  const double hold_z = sphere ? lo.z + 0.02 * (hi.z - lo.z) : lo.z;
  const double cap_radius =
      sphere ? std::sqrt(std::max(0.0, std::pow(0.5 * (hi.z - lo.z), 2) -
                                           std::pow(hold_z - 0.5 * (hi.z + lo.z), 2)))
             : INFINITY;
  if (sphere) {
    lattice.floor_z_m = hold_z;
    lattice.floor_cell_m = cap_radius / 3.0;
  }
  const double spacing = 0.5 * lattice.finest_m;
  std::vector<glm::dvec3> samples =
      contact_samples(vertices, triangles, top, 2.0 * lattice.fine_half_width_m, spacing);
  std::erase_if(samples, [&](const glm::dvec3& p) { return p.z < hold_z; });
  const auto build = [&] {
    if (o.lattice != "two-level")
      return sim::build_hex_lattice(vertices, triangles, lattice, samples);
    // Cells of four times the finest, split in 64 over the contact patch's box and, for the
    // sphere, over the cap it stands on (held on a few coarse nodes it rocks, and the Newton
    // steps do not converge).
    sim::TwoLevelOptions two;
    two.coarse_m = 4.0 * lattice.finest_m;
    two.factor = 4;
    const double half = lattice.fine_half_width_m;
    two.refine.push_back(
        {top - glm::dvec3(half, half, half), top + glm::dvec3(half, half, lattice.finest_m)});
    if (sphere) {
      const glm::dvec3 cap(top.x, top.y, hold_z);
      two.refine.push_back({cap - glm::dvec3(cap_radius, cap_radius, 0.0),
                            cap + glm::dvec3(cap_radius, cap_radius, two.coarse_m)});
    }
    two.floor_z_m = sphere ? hold_z : -INFINITY;
    return sim::build_two_level_lattice(vertices, triangles, two, samples);
  };
  sim::ElasticVolume volume(build(), material);
  const std::vector<sim::EmbeddedPoint> points = sim::embed_points(volume.lattice(), samples);
  // The rigid plane: the sphere's cut (its nodes within the cap), the block's bottom.
  const double floor_z = volume.lattice().axis[2].front();
  for (std::uint32_t i = 0; i < volume.positions().size(); ++i) {
    const glm::dvec3& p = volume.lattice().rest[i];
    const double off_axis = std::hypot(p.x - top.x, p.y - top.y);
    if (sphere ? (p.z <= floor_z && off_axis <= cap_radius) : p.z <= hold_z) volume.hold(i);
  }

  IndentCurve curve;
  curve.vertices = vertices.size();
  curve.cells = volume.lattice().cells.size();
  curve.nodes = volume.positions().size();
  curve.held_nodes = volume.held_count();
  curve.finest_cell_mm = lattice.finest_m * 1e3;
  curve.build_s = seconds_since(t0);
  const double e_star = youngs_kPa * 1e3 / (1.0 - poisson * poisson);
  const double body_r = sphere ? o.size_mm * 1e-3 : INFINITY;
  const auto t1 = std::chrono::steady_clock::now();
  ProgressLine progress(!o.json);
  for (int p = 1; p <= o.points; ++p) {
    const double depth = depth_max * double(p) / double(o.points);
    const glm::dvec3 centre(top.x, top.y, top.z + r - depth);
    sim::PressOptions press_options;
    // Penetration left by the contact: a thousandth of the depth moves the force by about as
    // much (Hertz: F ~ d^1.5).
    press_options.penetration_tolerance_m = 1e-3 * depth;
    press_options.cg_tolerance = 1e-2;  // an inexact Newton step: the next one corrects it
    press_options.max_newton = 100;
    // The penalty as a pressure stiffness of 20 E / h over each sample's share of the surface
    // (its spacing squared): the multipliers carry the contact force, the penalty only how fast
    // they get there; stiffer, and the contact set flips from one Newton step to the next.
    press_options.penalty_N_per_m = 20.0 * youngs_kPa * 1e3 * spacing * spacing / lattice.finest_m;
    const sim::PressResult press = volume.press_sphere(points, centre, r, press_options);
    curve.depth_mm.push_back(depth * 1e3);
    curve.force_N.push_back(press.probe_force_N.z);
    curve.hertz_N.push_back(hertz_force(depth, e_star, r, body_r, sphere));
    curve.newton_iterations += press.newton_iterations;
    curve.cg_iterations += press.cg_iterations;
    curve.converged = curve.converged && press.converged;
    progress.show("indent", std::size_t(p), std::size_t(o.points));
  }
  curve.solve_s = seconds_since(t1);
  return curve;
}

}  // namespace bisturi::cli
