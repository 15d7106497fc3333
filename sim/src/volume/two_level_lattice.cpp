// A lattice of coarse cells with a box of fine ones (hex_lattice.h): the fine lattice's
// positions everywhere, a coarse cell spanning factor^3 of them.

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include <glm/common.hpp>

#include "bisturi/sim/volume/hex_lattice.h"
#include "inside_columns.h"

namespace bisturi::sim {

namespace {

/// The fine grid over the surface's box: its low corner, coarse cells per axis and fine side.
struct FineGrid {
  glm::dvec3 lo{0.0};
  std::array<std::size_t, 3> coarse{};
  double fine_m = 0.0;
};

FineGrid fine_grid(std::span<const glm::dvec3> vertices,
                   std::span<const std::array<std::uint32_t, 3>> triangles,
                   const TwoLevelOptions& options) {
  if (vertices.empty() || triangles.empty())
    throw std::invalid_argument("two-level lattice: the surface is empty");
  if (!(options.coarse_m > 0.0) || options.factor < 1 || options.fill_samples < 1)
    throw std::invalid_argument(
        "two-level lattice: need a positive cell size, factor >= 1 and fill_samples >= 1");
  FineGrid g;
  g.fine_m = options.coarse_m / options.factor;
  glm::dvec3 lo(INFINITY), hi(-INFINITY);
  for (const glm::dvec3& v : vertices) {
    lo = glm::min(lo, v);
    hi = glm::max(hi, v);
  }
  lo -= glm::dvec3(0.1 * g.fine_m);
  hi += glm::dvec3(0.1 * g.fine_m);
  if (options.floor_z_m > lo.z) lo.z = options.floor_z_m;
  if (!(hi.z > lo.z))
    throw std::invalid_argument("two-level lattice: the floor is above the solid");
  g.lo = lo;
  for (int a = 0; a < 3; ++a)
    g.coarse[std::size_t(a)] =
        static_cast<std::size_t>(std::ceil((hi[a] - lo[a]) / options.coarse_m));
  return g;
}

FineShares shares_on(const FineGrid& g, std::span<const glm::dvec3> vertices,
                     std::span<const std::array<std::uint32_t, 3>> triangles, std::uint32_t factor,
                     int s) {
  FineShares out;
  out.lo = g.lo;
  out.fine_m = g.fine_m;
  out.samples = s;
  std::array<std::vector<double>, 3> samples;
  for (std::size_t a = 0; a < 3; ++a) {
    out.dims[a] = g.coarse[a] * factor;
    for (std::size_t c = 0; c < out.dims[a]; ++c)
      for (int q = 0; q < s; ++q)
        samples[a].push_back(g.lo[int(a)] + double(c) * g.fine_m + g.fine_m * (q + 0.5) / s);
  }
  const std::vector<std::uint8_t> inside =
      inside_columns(vertices, triangles, samples[0], samples[1], samples[2]);
  const auto& d = out.dims;
  out.share.assign(d[0] * d[1] * d[2], 0.0);
  const double per_sample = 1.0 / double(s * s * s);
  const std::size_t sx = samples[0].size(), sy = samples[1].size();
  for (std::size_t k = 0; k < samples[2].size(); ++k)
    for (std::size_t j = 0; j < sy; ++j)
      for (std::size_t i = 0; i < sx; ++i)
        if (inside[(k * sy + j) * sx + i])
          out.share[((k / std::size_t(s)) * d[1] + j / std::size_t(s)) * d[0] +
                    i / std::size_t(s)] += per_sample;
  return out;
}

}  // namespace

FineShares two_level_fine_shares(std::span<const glm::dvec3> vertices,
                                 std::span<const std::array<std::uint32_t, 3>> triangles,
                                 const TwoLevelOptions& options) {
  return shares_on(fine_grid(vertices, triangles, options), vertices, triangles, options.factor,
                   options.fill_samples);
}

HexLattice build_two_level_lattice(std::span<const glm::dvec3> vertices,
                                   std::span<const std::array<std::uint32_t, 3>> triangles,
                                   const TwoLevelOptions& options,
                                   std::span<const glm::dvec3> also_embed,
                                   const FineShares* shares) {
  const double coarse_m = options.coarse_m;
  const std::uint32_t factor = options.factor;
  const FineGrid grid = fine_grid(vertices, triangles, options);
  const double fine_m = grid.fine_m;
  const glm::dvec3 lo = grid.lo;
  const std::array<std::size_t, 3> coarse = grid.coarse;  // coarse cells per axis
  HexLattice lattice;
  for (std::size_t a = 0; a < 3; ++a)
    for (std::size_t i = 0; i <= coarse[a] * factor; ++i)
      lattice.axis[a].push_back(lo[int(a)] + double(i) * fine_m);
  const auto d = lattice.cell_dims();
  const auto fine_index = [&](std::size_t i, std::size_t j, std::size_t k) {
    return (k * d[1] + j) * d[0] + i;
  };
  // Each fine position's inside share: the earlier build's where the grid is the same (a cut
  // leaves the surface's box and what it holds as they were).
  const int s = options.fill_samples;
  const bool same_grid = shares != nullptr && shares->lo == lo && shares->dims == d &&
                         shares->fine_m == fine_m && shares->samples == s;
  FineShares computed;
  if (!same_grid) computed = shares_on(grid, vertices, triangles, factor, s);
  const std::vector<double>& fill = same_grid ? shares->share : computed.share;
  const double per_sample = 1.0 / double(s * s * s);
  std::vector<std::uint8_t> holds_point(fill.size(), 0);
  for (const auto& points : {vertices, also_embed}) {
    for (const glm::dvec3& v : points) {
      if (v.z < lo.z) continue;  // below the floor: cut away
      const auto [i, j, k] = lattice.locate(v);
      holds_point[fine_index(i, j, k)] = 1;
    }
  }

  lattice.cell_at.assign(fill.size(), -1);
  lattice.cell_span.clear();
  std::vector<std::int32_t> node_id((d[0] + 1) * (d[1] + 1) * (d[2] + 1), -1);
  const auto node_index = [&](std::size_t i, std::size_t j, std::size_t k) {
    return (k * (d[1] + 1) + j) * (d[0] + 1) + i;
  };
  // A cell of `n` positions from (i, j, k), kept with its fill.
  const auto add_cell = [&](std::size_t i, std::size_t j, std::size_t k, std::uint32_t n,
                            double cell_fill) {
    std::array<std::uint32_t, 8> nodes{};
    for (std::uint32_t corner = 0; corner < 8; ++corner) {
      const std::size_t ni = i + n * (corner & 1u), nj = j + n * ((corner >> 1) & 1u),
                        nk = k + n * ((corner >> 2) & 1u);
      std::int32_t& id = node_id[node_index(ni, nj, nk)];
      if (id < 0) {
        id = static_cast<std::int32_t>(lattice.rest.size());
        lattice.rest.emplace_back(lattice.axis[0][ni], lattice.axis[1][nj], lattice.axis[2][nk]);
      }
      nodes[corner] = static_cast<std::uint32_t>(id);
    }
    const auto cell = static_cast<std::int32_t>(lattice.cells.size());
    for (std::size_t c = k; c < k + n; ++c)
      for (std::size_t b = j; b < j + n; ++b)
        for (std::size_t a = i; a < i + n; ++a)
          lattice.cell_at[fine_index(a, b, c)] = cell;
    lattice.cells.push_back(nodes);
    lattice.cell_ijk.push_back({static_cast<std::uint32_t>(i), static_cast<std::uint32_t>(j),
                                static_cast<std::uint32_t>(k)});
    lattice.cell_span.push_back(n);
    lattice.fill.push_back(std::min(1.0, cell_fill));
  };
  // Coarse cells first (their corners are the masters), then the fine ones in the box.
  const auto refined = [&](std::size_t ci, std::size_t cj, std::size_t ck) {
    const glm::dvec3 cell_lo = lo + coarse_m * glm::dvec3(double(ci), double(cj), double(ck));
    const glm::dvec3 cell_hi = cell_lo + glm::dvec3(coarse_m);
    return std::any_of(options.refine.begin(), options.refine.end(), [&](const auto& box) {
      return glm::all(glm::lessThan(cell_lo, box.hi)) &&
             glm::all(glm::greaterThan(cell_hi, box.lo));
    });
  };
  const std::size_t f = factor;
  for (int pass = 0; pass < 2; ++pass) {
    for (std::size_t ck = 0; ck < coarse[2]; ++ck)
      for (std::size_t cj = 0; cj < coarse[1]; ++cj)
        for (std::size_t ci = 0; ci < coarse[0]; ++ci) {
          const bool fine = refined(ci, cj, ck);
          if (fine != (pass == 1)) continue;
          double total = 0.0;
          bool holds = false;
          for (std::size_t k = ck * f; k < (ck + 1) * f; ++k)
            for (std::size_t j = cj * f; j < (cj + 1) * f; ++j)
              for (std::size_t i = ci * f; i < (ci + 1) * f; ++i) {
                const std::size_t p = fine_index(i, j, k);
                if (fine && (fill[p] > 0.0 || holds_point[p]))
                  add_cell(i, j, k, 1, std::max(fill[p], per_sample));
                total += fill[p];
                holds = holds || holds_point[p];
              }
          if (fine) continue;
          const double share = total / double(f * f * f);
          if (share > 0.0 || holds)
            add_cell(ci * f, cj * f, ck * f, factor,
                     std::max(share, per_sample / double(f * f * f)));
        }
  }

  // Fine nodes on a kept coarse cell's boundary, not at its corners, hang on its corners.
  std::vector<std::uint8_t> hangs(lattice.rest.size(), 0);
  for (std::size_t c = 0; c < lattice.cells.size() && factor > 1; ++c) {
    if (lattice.cell_span[c] == 1) continue;
    const auto& o = lattice.cell_ijk[c];
    for (std::size_t k = 0; k <= f; ++k)
      for (std::size_t j = 0; j <= f; ++j)
        for (std::size_t i = 0; i <= f; ++i) {
          const bool on_boundary = i == 0 || i == f || j == 0 || j == f || k == 0 || k == f;
          const bool at_corner = (i % f == 0) && (j % f == 0) && (k % f == 0);
          if (!on_boundary || at_corner) continue;
          const std::int32_t id = node_id[node_index(o[0] + i, o[1] + j, o[2] + k)];
          if (id < 0 || hangs[std::size_t(id)]) continue;
          hangs[std::size_t(id)] = 1;
          const double t[3] = {double(i) / double(f), double(j) / double(f), double(k) / double(f)};
          HangingNode h;
          h.node = static_cast<std::uint32_t>(id);
          for (std::uint32_t corner = 0; corner < 8; ++corner) {
            double w = 1.0;
            for (int a = 0; a < 3; ++a)
              w *= ((corner >> a) & 1u) ? t[a] : 1.0 - t[a];
            if (w <= 1e-12) continue;
            h.masters[h.masters_count] = lattice.cells[c][corner];
            h.weights[h.masters_count] = w;
            ++h.masters_count;
          }
          lattice.hanging.push_back(h);
        }
  }
  return lattice;
}

}  // namespace bisturi::sim
