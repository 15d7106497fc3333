#include "surface/cube_cases.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/glm.hpp>

// How a cell's surface is derived.
//
// 1. A cube edge is crossed when its two corners differ (inside: value > iso).
// 2. On each face, walk its corners counter-clockwise as seen from outside the cell. Crossings
//    alternate between out->in and in->out. Every out->in crossing starts a segment that ends at an
//    in->out crossing of the same face: the one after it when inside corners are cut off, the one
//    before it when an outside corner is cut off. With two crossings there is one choice; with four
//    (two diagonal inside corners: an ambiguous face) the asymptotic decider picks it, and the same
//    outcome is used by the cell on the other side of the face. A segment so oriented has the
//    surface's inside on its right when seen from the outside region, so the cell polygons below
//    have normals that point from inside to outside.
// 3. Each crossed cube edge lies on two faces, which the counter-clockwise walks traverse in
//    opposite directions: it ends exactly one segment and starts exactly one. The successor map is
//    a permutation of the crossed edges, whose cycles are the cell's polygons (3 to 12 vertices,
//    vertex-disjoint).
// 4. Polygons are triangulated by dynamic programming over diagonals (minimum sum of
//    (sum of squared sides) / area, measured with the vertices at edge midpoints). A diagonal that
//    joins two vertices of one ambiguous face is never used: the neighbouring cell may draw the
//    same chord, and the edge would then have four triangles. A polygon without any admissible
//    triangulation gets an extra vertex at its centroid and a fan.
//
// Adjacent cells share the face segments (traversed in opposite directions), so the union of the
// cells' triangles is a consistently oriented 2-manifold, closed except at the volume's border.
// Only face ambiguities are resolved; the interior ambiguity of a cell (a tunnel through the cell
// between two opposite corners, cases 4 / 13 of Chernyaev) is not reconstructed: such cells take
// the separated configuration implied by their faces, which is still a valid manifold.

namespace bisturi::surface {
namespace {

int edge_index(int c1, int c2) {
  const int diff = c1 ^ c2;
  const int lo = std::min(c1, c2);
  const int x = lo & 1, y = (lo >> 1) & 1, z = (lo >> 2) & 1;
  if (diff == 1) return y + 2 * z;
  if (diff == 2) return 4 + x + 2 * z;
  return 8 + x + 2 * y;
}

glm::dvec3 corner_position(int c) {
  return {double(c & 1), double((c >> 1) & 1), double((c >> 2) & 1)};
}

struct Geometry {
  std::array<CubeFace, 6> faces{};
  std::array<std::array<std::uint8_t, 2>, 12> edge_corners{};
  std::array<glm::dvec3, 12> midpoints{};
};

Geometry make_geometry() {
  Geometry g;
  for (int axis = 0; axis < 3; ++axis) {
    const int u = (axis + 1) % 3, v = (axis + 2) % 3;
    for (int side = 0; side < 2; ++side) {
      const int base = side << axis;
      // (u, v) -> counter-clockwise around e_u x e_v = e_axis: right for the face at side 1.
      std::array<int, 4> cyc{base, base | (1 << u), base | (1 << u) | (1 << v), base | (1 << v)};
      if (side == 0) std::reverse(cyc.begin(), cyc.end());
      CubeFace& face = g.faces[2 * static_cast<std::size_t>(axis) + static_cast<std::size_t>(side)];
      for (std::size_t m = 0; m < 4; ++m) {
        face.corners[m] = static_cast<std::uint8_t>(cyc[m]);
        face.edges[m] = static_cast<std::uint8_t>(edge_index(cyc[m], cyc[(m + 1) % 4]));
      }
    }
  }
  for (int c = 0; c < 8; ++c) {
    for (int axis = 0; axis < 3; ++axis) {
      if ((c >> axis) & 1) continue;
      const int e = edge_index(c, c | (1 << axis));
      g.edge_corners[static_cast<std::size_t>(e)] = {static_cast<std::uint8_t>(c),
                                                     static_cast<std::uint8_t>(c | (1 << axis))};
      g.midpoints[static_cast<std::size_t>(e)] =
          0.5 * (corner_position(c) + corner_position(c | (1 << axis)));
    }
  }
  return g;
}

const Geometry& geometry() {
  static const Geometry g = make_geometry();
  return g;
}

std::uint8_t ambiguous_faces(std::uint8_t inside) {
  std::uint8_t mask = 0;
  for (std::size_t f = 0; f < 6; ++f) {
    const CubeFace& face = geometry().faces[f];
    const int a = (inside >> face.corners[0]) & 1, b = (inside >> face.corners[1]) & 1;
    const int c = (inside >> face.corners[2]) & 1, d = (inside >> face.corners[3]) & 1;
    if (a == c && b == d && a != b) mask = static_cast<std::uint8_t>(mask | (1 << f));
  }
  return mask;
}

double triangle_cost(const glm::dvec3& a, const glm::dvec3& b, const glm::dvec3& c) {
  const double area = 0.5 * glm::length(glm::cross(b - a, c - a));
  const double sides = glm::dot(b - a, b - a) + glm::dot(c - b, c - b) + glm::dot(a - c, a - c);
  return area > 1e-12 ? sides / area : 1e12;
}

/// Appends the triangles of one polygon to `cases` (extra vertex when needed).
void triangulate(const std::vector<std::uint8_t>& poly, std::uint8_t ambiguous, CubeCases& cases,
                 CaseEntry& entry) {
  const Geometry& g = geometry();
  const std::size_t n = poly.size();
  auto forbidden = [&](std::size_t i, std::size_t j) {
    for (std::size_t f = 0; f < 6; ++f) {
      if (!((ambiguous >> f) & 1)) continue;
      const auto& edges = g.faces[f].edges;
      const bool has_i = std::find(edges.begin(), edges.end(), poly[i]) != edges.end();
      const bool has_j = std::find(edges.begin(), edges.end(), poly[j]) != edges.end();
      if (has_i && has_j) return true;
    }
    return false;
  };
  constexpr double kInf = std::numeric_limits<double>::infinity();
  std::vector<double> cost(n * n, kInf);
  std::vector<std::size_t> split(n * n, 0);
  for (std::size_t i = 0; i + 1 < n; ++i)
    cost[i * n + i + 1] = 0.0;
  for (std::size_t len = 2; len < n; ++len) {
    for (std::size_t i = 0; i + len < n; ++i) {
      const std::size_t j = i + len;
      const bool chord = !(i == 0 && j == n - 1);
      if (chord && forbidden(i, j)) continue;
      for (std::size_t k = i + 1; k < j; ++k) {
        const double c =
            cost[i * n + k] + cost[k * n + j] +
            triangle_cost(g.midpoints[poly[i]], g.midpoints[poly[k]], g.midpoints[poly[j]]);
        if (c < cost[i * n + j]) {
          cost[i * n + j] = c;
          split[i * n + j] = k;
        }
      }
    }
  }
  if (cost[n - 1] < kInf) {
    std::vector<std::pair<std::size_t, std::size_t>> stack{{0, n - 1}};
    while (!stack.empty()) {
      const auto [i, j] = stack.back();
      stack.pop_back();
      if (j - i < 2) continue;
      const std::size_t k = split[i * n + j];
      cases.triangle_codes.insert(cases.triangle_codes.end(), {poly[i], poly[k], poly[j]});
      ++entry.triangle_count;
      stack.emplace_back(i, k);
      stack.emplace_back(k, j);
    }
    return;
  }
  // No admissible diagonal triangulation: fan around the polygon's centroid.
  const auto extra = static_cast<std::uint8_t>(12 + entry.extra_count);
  ExtraVertex ev;
  ev.first_code = static_cast<std::uint32_t>(cases.extra_codes.size());
  ev.code_count = static_cast<std::uint32_t>(n);
  cases.extra_codes.insert(cases.extra_codes.end(), poly.begin(), poly.end());
  cases.extras.push_back(ev);
  ++entry.extra_count;
  for (std::size_t i = 0; i < n; ++i) {
    cases.triangle_codes.insert(cases.triangle_codes.end(), {poly[i], poly[(i + 1) % n], extra});
    ++entry.triangle_count;
  }
}

CubeCases build_cases() {
  const Geometry& g = geometry();
  CubeCases cases;
  cases.faces = g.faces;
  cases.edge_corners = g.edge_corners;
  for (int config = 0; config < 256; ++config) {
    const auto inside = static_cast<std::uint8_t>(config);
    CubeCase& cc = cases.cases[static_cast<std::size_t>(config)];
    cc.ambiguous_faces = ambiguous_faces(inside);
    cc.ambiguous_count = static_cast<std::uint8_t>(__builtin_popcount(cc.ambiguous_faces));
    cc.first_entry = static_cast<std::uint32_t>(cases.entries.size());
    for (std::size_t e = 0; e < 12; ++e) {
      const auto [c1, c2] = g.edge_corners[e];
      if (((inside >> c1) & 1) != ((inside >> c2) & 1)) {
        cc.crossed_edges = static_cast<std::uint16_t>(cc.crossed_edges | (1u << e));
      }
    }
    for (unsigned bits = 0; bits < (1u << cc.ambiguous_count); ++bits) {
      // Spread the compact outcome bits onto the ambiguous faces.
      std::uint8_t connected = 0;
      unsigned b = 0;
      for (int f = 0; f < 6; ++f) {
        if (!((cc.ambiguous_faces >> f) & 1)) continue;
        if ((bits >> b) & 1) connected = static_cast<std::uint8_t>(connected | (1 << f));
        ++b;
      }
      CaseEntry entry;
      entry.first_triangle = static_cast<std::uint32_t>(cases.triangle_codes.size() / 3);
      entry.first_extra = static_cast<std::uint32_t>(cases.extras.size());
      for (const auto& poly : cell_polygons(inside, connected)) {
        triangulate(poly, cc.ambiguous_faces, cases, entry);
      }
      cases.entries.push_back(entry);
    }
  }
  return cases;
}

}  // namespace

std::vector<std::vector<std::uint8_t>> cell_polygons(std::uint8_t inside,
                                                     std::uint8_t connected_faces) {
  const Geometry& g = geometry();
  std::array<int, 12> next;
  next.fill(-1);
  for (std::size_t f = 0; f < 6; ++f) {
    const CubeFace& face = g.faces[f];
    std::array<int, 4> in{};
    for (std::size_t m = 0; m < 4; ++m)
      in[m] = (inside >> face.corners[m]) & 1;
    int crossings = 0;
    for (std::size_t m = 0; m < 4; ++m)
      crossings += in[m] != in[(m + 1) % 4] ? 1 : 0;
    for (std::size_t m = 0; m < 4; ++m) {
      if (!(in[m] == 0 && in[(m + 1) % 4] == 1)) continue;  // not an out->in crossing
      std::size_t end = 0;
      if (crossings == 2) {
        for (std::size_t q = 0; q < 4; ++q) {
          if (in[q] == 1 && in[(q + 1) % 4] == 0) end = q;
        }
      } else {
        const bool joined = ((connected_faces >> f) & 1) != 0;
        end = joined ? (m + 3) % 4 : (m + 1) % 4;
      }
      next[face.edges[m]] = face.edges[end];
    }
  }
  std::vector<std::vector<std::uint8_t>> polygons;
  std::array<bool, 12> seen{};
  for (std::size_t e = 0; e < 12; ++e) {
    if (next[e] < 0 || seen[e]) continue;
    std::vector<std::uint8_t> poly;
    for (std::size_t c = e; !seen[c]; c = static_cast<std::size_t>(next[c])) {
      seen[c] = true;
      poly.push_back(static_cast<std::uint8_t>(c));
    }
    polygons.push_back(std::move(poly));
  }
  return polygons;
}

const CubeCases& cube_cases() {
  static const CubeCases cases = build_cases();
  return cases;
}

}  // namespace bisturi::surface
