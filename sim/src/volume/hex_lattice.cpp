#include "bisturi/sim/volume/hex_lattice.h"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <glm/common.hpp>

#include "inside_columns.h"

namespace bisturi::sim {

std::vector<double> graded_axis(double lo, double hi, double centre, double finest,
                                double fine_half_width, double growth, double coarsest,
                                double lo_cell) {
  if (!(hi > lo) || !(finest > 0.0) || !(growth >= 1.0) || !(coarsest >= finest))
    throw std::invalid_argument(
        "graded_axis: need hi > lo, finest > 0, growth >= 1, coarsest >= finest");
  // A centre within a cell of an end moves onto it: no sliver cell at the end.
  centre = std::clamp(centre, lo, hi);
  if (centre - lo < finest) centre = lo;
  if (hi - centre < finest) centre = hi;
  // Sizes going outwards from the centre on one side, until the side's length is covered.
  // `end_cell`: cells no larger than end_cell + (growth - 1) x their distance from the side's
  // end (0: no such limit).
  const auto side = [&](double length, double end_cell) {
    std::vector<double> sizes;
    double covered = 0.0, h = finest;
    while (covered < length - 1e-12 * (hi - lo)) {
      if (covered >= fine_half_width) h = std::min(h * growth, coarsest);
      double cell = h;
      if (end_cell > 0.0)
        cell = std::max(std::min(h, end_cell + (growth - 1.0) * (length - covered - h)), end_cell);
      sizes.push_back(std::min(cell, length - covered + 1e-15));
      covered += sizes.back();
    }
    // Scale the last cells so the side ends exactly at its end (the last one alone could be a
    // sliver).
    if (!sizes.empty()) {
      const double scale = length / covered;
      for (double& s : sizes)
        s *= scale;
    }
    return sizes;
  };
  const std::vector<double> down = side(centre - lo, lo_cell), up = side(hi - centre, 0.0);
  std::vector<double> x;
  x.reserve(down.size() + up.size() + 1);
  x.push_back(lo);
  double at = lo;
  for (auto it = down.rbegin(); it != down.rend(); ++it)
    x.push_back(at += *it);
  for (double s : up)
    x.push_back(at += s);
  x.front() = lo;
  x.back() = hi;
  // A centre on an end gives a repeated node: drop it.
  x.erase(std::unique(x.begin(), x.end(), [](double a, double b) { return b - a <= 0.0; }),
          x.end());
  return x;
}

std::array<std::uint32_t, 3> HexLattice::locate(const glm::dvec3& p) const {
  std::array<std::uint32_t, 3> ijk{};
  for (int a = 0; a < 3; ++a) {
    const std::vector<double>& x = axis[static_cast<std::size_t>(a)];
    const auto it = std::upper_bound(x.begin(), x.end(), p[a]);
    const auto i = std::clamp<std::ptrdiff_t>(it - x.begin() - 1, 0,
                                              static_cast<std::ptrdiff_t>(x.size()) - 2);
    ijk[static_cast<std::size_t>(a)] = static_cast<std::uint32_t>(i);
  }
  return ijk;
}

glm::dvec3 HexLattice::cell_sides(std::size_t c) const {
  const auto& ijk = cell_ijk[c];
  const std::uint32_t n = span(c);
  return {axis[0][ijk[0] + n] - axis[0][ijk[0]], axis[1][ijk[1] + n] - axis[1][ijk[1]],
          axis[2][ijk[2] + n] - axis[2][ijk[2]]};
}

glm::dvec3 HexLattice::cell_centre(std::size_t c) const {
  const auto& ijk = cell_ijk[c];
  return glm::dvec3(axis[0][ijk[0]], axis[1][ijk[1]], axis[2][ijk[2]]) + 0.5 * cell_sides(c);
}

std::int32_t HexLattice::kept_cell(const glm::dvec3& p) const {
  const auto [i, j, k] = locate(p);
  const auto d = cell_dims();
  return cell_at[(k * d[1] + j) * d[0] + i];
}

HexLattice build_hex_lattice(std::span<const glm::dvec3> vertices,
                             std::span<const std::array<std::uint32_t, 3>> triangles,
                             const LatticeOptions& o, std::span<const glm::dvec3> also_embed) {
  if (vertices.empty() || triangles.empty())
    throw std::invalid_argument("hex lattice: the surface is empty");
  if (o.fill_samples < 1) throw std::invalid_argument("hex lattice: fill_samples must be >= 1");
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::dvec3& v : vertices) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
  }
  // A margin of a tenth of the finest cell: no surface vertex on the lattice's outer faces.
  lo -= glm::dvec3(0.1 * o.finest_m);
  hi += glm::dvec3(0.1 * o.finest_m);
  if (o.floor_z_m > lo.z) lo.z = o.floor_z_m;
  if (!(hi.z > lo.z)) throw std::invalid_argument("hex lattice: the floor is above the solid");
  HexLattice lattice;
  for (int a = 0; a < 3; ++a) {
    lattice.axis[static_cast<std::size_t>(a)] =
        graded_axis(lo[a], hi[a], o.focus_m[a], o.finest_m, o.fine_half_width_m, o.growth,
                    std::max(o.coarsest_m, o.finest_m), a == 2 ? o.floor_cell_m : 0.0);
  }
  const auto d = lattice.cell_dims();
  const std::size_t n_cells = d[0] * d[1] * d[2];

  // The inside share of every cell, from fill_samples^3 points each (ray parity along z).
  const int s = o.fill_samples;
  std::array<std::vector<double>, 3> samples;
  for (int a = 0; a < 3; ++a) {
    const std::vector<double>& x = lattice.axis[static_cast<std::size_t>(a)];
    for (std::size_t c = 0; c + 1 < x.size(); ++c) {
      for (int q = 0; q < s; ++q)
        samples[static_cast<std::size_t>(a)].push_back(x[c] + (x[c + 1] - x[c]) * (q + 0.5) / s);
    }
  }
  const std::vector<std::uint8_t> inside =
      inside_columns(vertices, triangles, samples[0], samples[1], samples[2]);
  std::vector<double> fill(n_cells, 0.0);
  const std::size_t sx = samples[0].size(), sy = samples[1].size();
  const double per_sample = 1.0 / double(s * s * s);
  for (std::size_t k = 0; k < samples[2].size(); ++k) {
    for (std::size_t j = 0; j < sy; ++j) {
      for (std::size_t i = 0; i < sx; ++i) {
        if (!inside[(k * sy + j) * sx + i]) continue;
        const std::size_t cell =
            ((k / std::size_t(s)) * d[1] + j / std::size_t(s)) * d[0] + i / std::size_t(s);
        fill[cell] += per_sample;
      }
    }
  }
  // Cells holding a surface vertex are kept however little of them is inside: the vertex is
  // embedded in them. Their stiffness then counts at least one sample's share.
  for (const auto& points : {vertices, also_embed}) {
    for (const glm::dvec3& v : points) {
      if (v.z < lo.z) continue;  // below the floor: cut away
      const auto [i, j, k] = lattice.locate(v);
      double& f = fill[(k * d[1] + j) * d[0] + i];
      f = std::max(f, per_sample);
    }
  }

  lattice.cell_at.assign(n_cells, -1);
  std::vector<std::int32_t> node_id((d[0] + 1) * (d[1] + 1) * (d[2] + 1), -1);
  for (std::size_t k = 0; k < d[2]; ++k) {
    for (std::size_t j = 0; j < d[1]; ++j) {
      for (std::size_t i = 0; i < d[0]; ++i) {
        const std::size_t c = (k * d[1] + j) * d[0] + i;
        if (fill[c] <= 0.0) continue;
        std::array<std::uint32_t, 8> nodes{};
        for (std::uint32_t corner = 0; corner < 8; ++corner) {
          const std::size_t ni = i + (corner & 1u), nj = j + ((corner >> 1) & 1u),
                            nk = k + ((corner >> 2) & 1u);
          std::int32_t& id = node_id[(nk * (d[1] + 1) + nj) * (d[0] + 1) + ni];
          if (id < 0) {
            id = static_cast<std::int32_t>(lattice.rest.size());
            lattice.rest.emplace_back(lattice.axis[0][ni], lattice.axis[1][nj],
                                      lattice.axis[2][nk]);
          }
          nodes[corner] = static_cast<std::uint32_t>(id);
        }
        lattice.cell_at[c] = static_cast<std::int32_t>(lattice.cells.size());
        lattice.cells.push_back(nodes);
        lattice.cell_ijk.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j),
                                    static_cast<std::uint32_t>(k)});
        lattice.fill.push_back(std::min(1.0, fill[c]));
      }
    }
  }
  return lattice;
}

}  // namespace bisturi::sim
