#include "inside_columns.h"

#include <algorithm>
#include <cmath>

namespace bisturi::sim {

std::vector<std::uint8_t> inside_columns(std::span<const glm::dvec3> vertices,
                                         std::span<const std::array<std::uint32_t, 3>> triangles,
                                         std::span<const double> xs, std::span<const double> ys,
                                         std::span<const double> zs) {
  std::vector<std::uint8_t> inside(xs.size() * ys.size() * zs.size(), 0);
  if (xs.empty() || ys.empty() || zs.empty() || triangles.empty()) return inside;
  // Buckets over the columns' xy range, about one triangle's size each.
  const double x0 = xs.front(), x1 = xs.back(), y0 = ys.front(), y1 = ys.back();
  const double extent = std::max(x1 - x0, y1 - y0);
  const auto nb =
      static_cast<std::size_t>(std::clamp(std::sqrt(double(triangles.size())) / 2.0, 1.0, 512.0));
  const double bw = std::max(x1 - x0, 1e-12) / double(nb),
               bh = std::max(y1 - y0, 1e-12) / double(nb);
  const auto bucket_of = [&](double v, double v0, double w) {
    return static_cast<std::size_t>(std::clamp((v - v0) / w, 0.0, double(nb - 1)));
  };
  std::vector<std::vector<std::uint32_t>> buckets(nb * nb);
  for (std::uint32_t t = 0; t < triangles.size(); ++t) {
    const glm::dvec3& a = vertices[triangles[t][0]];
    const glm::dvec3& b = vertices[triangles[t][1]];
    const glm::dvec3& c = vertices[triangles[t][2]];
    const double tx0 = std::min({a.x, b.x, c.x}), tx1 = std::max({a.x, b.x, c.x});
    const double ty0 = std::min({a.y, b.y, c.y}), ty1 = std::max({a.y, b.y, c.y});
    if (tx1 < x0 || tx0 > x1 || ty1 < y0 || ty0 > y1) continue;
    for (std::size_t by = bucket_of(ty0, y0, bh); by <= bucket_of(ty1, y0, bh); ++by)
      for (std::size_t bx = bucket_of(tx0, x0, bw); bx <= bucket_of(tx1, x0, bw); ++bx)
        buckets[by * nb + bx].push_back(t);
  }
  // Off the grid by an irrational share of the extent: no ray through a vertex or along an edge.
  const double nudge_x = 1e-9 * extent * std::sqrt(2.0), nudge_y = 1e-9 * extent * std::sqrt(3.0);
  std::vector<double> crossings;
  for (std::size_t j = 0; j < ys.size(); ++j) {
    for (std::size_t i = 0; i < xs.size(); ++i) {
      const double px = xs[i] + nudge_x, py = ys[j] + nudge_y;
      crossings.clear();
      for (std::uint32_t t : buckets[bucket_of(py, y0, bh) * nb + bucket_of(px, x0, bw)]) {
        const glm::dvec3& a = vertices[triangles[t][0]];
        const glm::dvec3& b = vertices[triangles[t][1]];
        const glm::dvec3& c = vertices[triangles[t][2]];
        // Barycentric coordinates of (px, py) in the triangle's xy projection.
        const double det = (b.x - a.x) * (c.y - a.y) - (c.x - a.x) * (b.y - a.y);
        if (det == 0.0) continue;
        const double u = ((px - a.x) * (c.y - a.y) - (c.x - a.x) * (py - a.y)) / det;
        const double v = ((b.x - a.x) * (py - a.y) - (px - a.x) * (b.y - a.y)) / det;
        if (u < 0.0 || v < 0.0 || u + v > 1.0) continue;
        crossings.push_back(a.z + u * (b.z - a.z) + v * (c.z - a.z));
      }
      std::sort(crossings.begin(), crossings.end());
      std::size_t below = 0;
      for (std::size_t k = 0; k < zs.size(); ++k) {
        while (below < crossings.size() && crossings[below] < zs[k])
          ++below;
        if (below % 2 == 1) inside[(k * ys.size() + j) * xs.size() + i] = 1;
      }
    }
  }
  return inside;
}

}  // namespace bisturi::sim
