#include "bisturi/sim/volume/embedding.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

namespace bisturi::sim {

namespace {

/// Trilinear weights of `point` in kept cell `cell`, its parameters clamped to the cell or not.
EmbeddedPoint weights_in(const HexLattice& lattice, std::int32_t cell, const glm::dvec3& point,
                         bool clamp) {
  const auto& ijk = lattice.cell_ijk[static_cast<std::size_t>(cell)];
  const std::size_t n = lattice.span(static_cast<std::size_t>(cell));
  glm::dvec3 t;
  for (int a = 0; a < 3; ++a) {
    const std::vector<double>& x = lattice.axis[static_cast<std::size_t>(a)];
    const std::size_t i = ijk[static_cast<std::size_t>(a)];
    t[a] = (point[a] - x[i]) / (x[i + n] - x[i]);
    if (clamp) t[a] = std::clamp(t[a], 0.0, 1.0);
  }
  EmbeddedPoint e;
  e.cell = static_cast<std::uint32_t>(cell);
  for (int c = 0; c < 8; ++c) {
    e.weights[static_cast<std::size_t>(c)] = ((c & 1) ? t.x : 1.0 - t.x) *
                                             (((c >> 1) & 1) ? t.y : 1.0 - t.y) *
                                             (((c >> 2) & 1) ? t.z : 1.0 - t.z);
  }
  return e;
}

}  // namespace

std::optional<EmbeddedPoint> embed_point(const HexLattice& lattice, const glm::dvec3& point) {
  const std::int32_t cell = lattice.kept_cell(point);
  if (cell < 0) return std::nullopt;
  return weights_in(lattice, cell, point, true);
}

std::optional<EmbeddedPoint> embed_point_nearest(const HexLattice& lattice,
                                                 const glm::dvec3& point) {
  if (const auto inside = embed_point(lattice, point)) return inside;
  if (lattice.cells.empty()) return std::nullopt;
  std::int32_t best = 0;
  double best_d2 = std::numeric_limits<double>::infinity();
  for (std::size_t c = 0; c < lattice.cells.size(); ++c) {
    const glm::dvec3 lo = lattice.rest[lattice.cells[c][0]];
    const glm::dvec3 hi = lattice.rest[lattice.cells[c][7]];
    const glm::dvec3 gap = glm::max(glm::max(lo - point, point - hi), glm::dvec3(0.0));
    const double d2 = glm::dot(gap, gap);
    if (d2 < best_d2) {
      best_d2 = d2;
      best = static_cast<std::int32_t>(c);
    }
  }
  return weights_in(lattice, best, point, false);
}

EmbeddedPoint embed_point_in(const HexLattice& lattice, std::uint32_t cell,
                             const glm::dvec3& point) {
  return weights_in(lattice, static_cast<std::int32_t>(cell), point, false);
}

std::vector<EmbeddedPoint> embed_points(const HexLattice& lattice,
                                        std::span<const glm::dvec3> points) {
  std::vector<EmbeddedPoint> out;
  out.reserve(points.size());
  for (std::size_t p = 0; p < points.size(); ++p) {
    const std::optional<EmbeddedPoint> e = embed_point(lattice, points[p]);
    if (!e) {
      throw std::invalid_argument("embed_points: point " + std::to_string(p) +
                                  " lies in no cell of the lattice");
    }
    out.push_back(*e);
  }
  return out;
}

glm::dvec3 embedded_position(const HexLattice& lattice, std::span<const glm::dvec3> nodes,
                             const EmbeddedPoint& point) {
  glm::dvec3 p(0.0);
  const auto& cell = lattice.cells[point.cell];
  for (std::size_t c = 0; c < 8; ++c)
    p += point.weights[c] * nodes[cell[c]];
  return p;
}

}  // namespace bisturi::sim
