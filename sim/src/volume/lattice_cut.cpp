#include "bisturi/sim/volume/lattice_cut.h"

#include <algorithm>
#include <limits>
#include <map>
#include <numeric>
#include <stdexcept>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "bisturi/sim/collision.h"

namespace bisturi::sim {
namespace {

using Triangle = std::array<glm::dvec3, 3>;

/// The quads between consecutive samples as triangles, each entry moved `reach` out along its
/// blade. A blade that barely moved between samples (one is taken each tissue step) gives no
/// quad: samples nearer than `min_step` to the last one kept are skipped.
std::vector<Triangle> sheet_triangles(const BladeSheet& sheet, double reach, double min_step) {
  std::vector<glm::dvec3> entry, tip;
  glm::dvec3 last_entry(0.0);
  for (std::size_t i = 0; i < sheet.entry_m.size(); ++i) {
    if (!tip.empty() && glm::length(sheet.tip_m[i] - tip.back()) < min_step &&
        glm::length(sheet.entry_m[i] - last_entry) < min_step)
      continue;
    last_entry = sheet.entry_m[i];
    const glm::dvec3 out = sheet.entry_m[i] - sheet.tip_m[i];
    const double length = glm::length(out);
    entry.push_back(length > 0.0 ? sheet.entry_m[i] + out * (reach / length) : sheet.entry_m[i]);
    tip.push_back(sheet.tip_m[i]);
  }
  std::vector<Triangle> out;
  const auto add = [&](const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
    if (glm::length(glm::cross(b - a, c - a)) > 1e-12) out.push_back({a, b, c});
  };
  for (std::size_t k = 0; k + 1 < entry.size(); ++k) {
    add(entry[k], entry[k + 1], tip[k + 1]);
    add(entry[k], tip[k + 1], tip[k]);
  }
  return out;
}

glm::dvec3 normal_of(const Triangle& t) {
  return glm::cross(t[1] - t[0], t[2] - t[0]);
}

/// Whether segment pq crosses triangle t: its ends on different sides of t's plane (a point on
/// the plane counts as in front) and the crossing inside t, edges included.
bool crosses(const glm::dvec3& p, const glm::dvec3& q, const Triangle& t) {
  const glm::dvec3 n = normal_of(t);
  const double sp = glm::dot(p - t[0], n), sq = glm::dot(q - t[0], n);
  if ((sp < 0.0) == (sq < 0.0)) return false;
  const glm::dvec3 x = p + (q - p) * (sp / (sp - sq));
  const double slack = -1e-9 * glm::dot(n, n);
  for (int e = 0; e < 3; ++e) {
    const glm::dvec3& a = t[static_cast<std::size_t>(e)];
    const glm::dvec3& b = t[static_cast<std::size_t>((e + 1) % 3)];
    if (glm::dot(glm::cross(b - a, x - a), n) < slack) return false;
  }
  return true;
}

bool crosses_any(const glm::dvec3& p, const glm::dvec3& q, const std::vector<Triangle>& sheet) {
  return std::any_of(sheet.begin(), sheet.end(),
                     [&](const Triangle& t) { return crosses(p, q, t); });
}

/// Lattice position ijk moved `by` along axis a.
std::array<std::uint32_t, 3> shifted(std::array<std::uint32_t, 3> ijk, std::size_t a,
                                     std::uint32_t by) {
  ijk[a] += by;
  return ijk;
}

/// Union-find over a node's (at most 8) cell corners.
struct Groups {
  std::array<std::uint32_t, 8> parent{};
  explicit Groups(std::size_t n) { std::iota(parent.begin(), parent.begin() + n, 0u); }
  std::uint32_t root(std::uint32_t i) {
    while (parent[i] != i)
      i = parent[i] = parent[parent[i]];
    return i;
  }
  void join(std::uint32_t a, std::uint32_t b) { parent[root(a)] = root(b); }
};

}  // namespace

LatticeSeparation separate_along_sheet(HexLattice& lattice, const BladeSheet& sheet,
                                       double reach_m) {
  if (sheet.entry_m.size() < 2 || sheet.tip_m.size() != sheet.entry_m.size())
    throw std::invalid_argument("separate_along_sheet: the sheet needs two samples or more");
  double finest = std::numeric_limits<double>::infinity();
  for (const auto& axis : lattice.axis)
    for (std::size_t i = 0; i + 1 < axis.size(); ++i)
      finest = std::min(finest, axis[i + 1] - axis[i]);
  const std::vector<Triangle> triangles = sheet_triangles(sheet, reach_m, 0.05 * finest);
  // A coarse cell's sheet reaches out as far as its side is the fine cells' (reach_m is the
  // finest cell's): cells of each size holding little tissue part alike.
  // (A map: the references handed out stay valid as spans are added.)
  std::map<std::uint32_t, std::vector<Triangle>> by_span;
  const auto sheet_of = [&](std::uint32_t span) -> const std::vector<Triangle>& {
    if (span <= 1) return triangles;
    const auto [it, added] = by_span.try_emplace(span);
    if (added) it->second = sheet_triangles(sheet, reach_m * span, 0.05 * finest);
    return it->second;
  };
  LatticeSeparation out;
  out.origin.resize(lattice.rest.size());
  std::iota(out.origin.begin(), out.origin.end(), 0u);
  if (triangles.empty()) return out;

  // Faces whose cells' centres lie across the sheet (only cells near its box are tried).
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (const Triangle& t : triangles)
    for (const glm::dvec3& p : t) {
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
  const std::size_t cells = lattice.cells.size();
  lattice.separated.resize(cells, 0);
  const auto d = lattice.cell_dims();
  std::vector<glm::dvec3> centre(cells);
  for (std::size_t c = 0; c < cells; ++c)
    centre[c] = lattice.cell_centre(c);
  std::vector<std::uint8_t> node_touched(lattice.rest.size(), 0);
  // In a two-level lattice a face parts between two cells of one size, and only where none of
  // its nodes hangs or is shared with a cell of the other size: those follow both sizes' cells.
  constexpr std::uint32_t kNoSpan = 0;
  std::vector<std::uint32_t> node_span(lattice.rest.size(), kNoSpan);
  std::vector<std::uint8_t> node_fixed(lattice.rest.size(), 0);
  for (std::size_t c = 0; c < cells; ++c)
    for (const std::uint32_t node : lattice.cells[c]) {
      if (node_span[node] != kNoSpan && node_span[node] != lattice.span(c)) node_fixed[node] = 1;
      node_span[node] = lattice.span(c);
    }
  for (const HangingNode& h : lattice.hanging)
    node_fixed[h.node] = 1;
  const auto face_free = [&](std::size_t c, std::size_t a) {
    for (std::uint32_t corner = 0; corner < 8; ++corner)
      if (((corner >> a) & 1u) && node_fixed[lattice.cells[c][corner]]) return false;
    return true;
  };
  for (std::size_t c = 0; c < cells; ++c) {
    const glm::dvec3 half = 0.5 * lattice.cell_sides(c);
    if (glm::any(glm::lessThan(centre[c] + 3.0 * half, lo)) ||
        glm::any(glm::greaterThan(centre[c] - 3.0 * half, hi)))
      continue;
    const std::uint32_t span = lattice.span(c);
    const auto& ijk = lattice.cell_ijk[c];
    for (std::size_t a = 0; a < 3; ++a) {
      std::array<std::size_t, 3> next{ijk[0], ijk[1], ijk[2]};
      next[a] += span;
      if (next[a] >= d[a]) continue;
      const std::int32_t n = lattice.cell_at[(next[2] * d[1] + next[1]) * d[0] + next[0]];
      if (n < 0 || lattice.span(std::size_t(n)) != span ||
          lattice.cell_ijk[std::size_t(n)] != shifted(lattice.cell_ijk[c], a, span) ||
          !face_free(c, a) || !crosses_any(centre[c], centre[std::size_t(n)], sheet_of(span)))
        continue;
      lattice.separated[c] |= std::uint8_t(1u << (2 * a + 1));
      lattice.separated[std::size_t(n)] |= std::uint8_t(1u << (2 * a));
      ++out.separated_faces;
      for (std::uint32_t corner = 0; corner < 8; ++corner)
        if ((corner >> a) & 1u) node_touched[lattice.cells[c][corner]] = 1;
    }
  }

  // Each touched node's corners, grouped by the cells still joined around it: cells sharing it
  // stay joined unless the segment between their centres crosses the sheet. The first group
  // keeps the node, each other takes a copy.
  std::vector<std::vector<std::pair<std::uint32_t, std::uint32_t>>> corners(lattice.rest.size());
  for (std::uint32_t c = 0; c < cells; ++c)
    for (std::uint32_t k = 0; k < 8; ++k)
      if (node_touched[lattice.cells[c][k]]) corners[lattice.cells[c][k]].push_back({c, k});
  for (std::uint32_t node = 0; node < node_touched.size(); ++node) {
    const auto& at = corners[node];
    if (at.size() < 2) continue;
    Groups groups(at.size());
    // A parted face's nodes are shared by cells of one size only.
    const std::vector<Triangle>& around = sheet_of(lattice.span(at[0].first));
    for (std::uint32_t i = 0; i < at.size(); ++i)
      for (std::uint32_t j = i + 1; j < at.size(); ++j)
        if (!crosses_any(centre[at[i].first], centre[at[j].first], around)) groups.join(i, j);
    std::array<std::int64_t, 8> copy_of_root;
    copy_of_root.fill(-1);
    const std::uint32_t kept = groups.root(0);
    for (std::uint32_t i = 0; i < at.size(); ++i) {
      const std::uint32_t r = groups.root(i);
      if (r == kept) continue;
      if (copy_of_root[r] < 0) {
        copy_of_root[r] = static_cast<std::int64_t>(lattice.rest.size());
        lattice.rest.push_back(lattice.rest[node]);
        out.origin.push_back(node);
        ++out.new_nodes;
      }
      lattice.cells[at[i].first][at[i].second] = static_cast<std::uint32_t>(copy_of_root[r]);
    }
  }
  lattice.cut_sheet.insert(lattice.cut_sheet.end(), triangles.begin(), triangles.end());
  return out;
}

int sheet_side(const HexLattice& lattice, const glm::dvec3& p) {
  double best = std::numeric_limits<double>::infinity();
  int side = 1;
  for (const Triangle& t : lattice.cut_sheet) {
    glm::dvec3 bc;
    const glm::dvec3 q = closest_point_on_triangle(p, t[0], t[1], t[2], bc);
    const double d = glm::dot(p - q, p - q);
    if (d >= best) continue;
    best = d;
    side = glm::dot(p - t[0], normal_of(t)) < 0.0 ? -1 : 1;
  }
  return side;
}

std::optional<EmbeddedPoint> embed_point_on_side(const HexLattice& lattice, const glm::dvec3& point,
                                                 int side) {
  std::optional<EmbeddedPoint> e = embed_point_nearest(lattice, point);
  if (!e || lattice.separated.empty() || lattice.separated[e->cell] == 0) return e;
  if (side == 0) side = sheet_side(lattice, point);
  const std::uint32_t c = e->cell;
  if (sheet_side(lattice, lattice.cell_centre(c)) == side) return e;
  // The nearest cell on the point's side across one of this cell's separated faces.
  const auto d = lattice.cell_dims();
  std::int32_t best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::uint32_t bit = 0; bit < 6; ++bit) {
    if (!((lattice.separated[c] >> bit) & 1u)) continue;
    std::array<std::int64_t, 3> ijk{lattice.cell_ijk[c][0], lattice.cell_ijk[c][1],
                                    lattice.cell_ijk[c][2]};
    ijk[bit / 2] += (bit & 1u) ? std::int64_t(lattice.span(c)) : -1;
    if (ijk[bit / 2] < 0 || ijk[bit / 2] >= static_cast<std::int64_t>(d[bit / 2])) continue;
    const std::int32_t n =
        lattice.cell_at[(std::size_t(ijk[2]) * d[1] + std::size_t(ijk[1])) * d[0] +
                        std::size_t(ijk[0])];
    if (n < 0) continue;
    const glm::dvec3 centre = lattice.cell_centre(std::size_t(n));
    if (sheet_side(lattice, centre) != side) continue;
    const double distance = glm::length(centre - point);
    if (distance < best_distance) {
      best_distance = distance;
      best = n;
    }
  }
  if (best < 0) return e;
  return embed_point_in(lattice, static_cast<std::uint32_t>(best), point);
}

}  // namespace bisturi::sim
