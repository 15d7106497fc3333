// The caps of a label's surface over its last slices (see label_caps.h).

#include "label_caps.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

namespace bisturi {

namespace {

/// A region's radius (its largest in-slice distance) in its last slice and in the two slices
/// before it, over the same samples (0 where there is no such slice).
struct Radii {
  float last = -1.0F, before = 0.0F, before2 = 0.0F;
};

/// Per sample of slice k: the radii of its 4-connected inside region (last 0 outside), the slices
/// before it being k - step and k - 2 step.
void region_radii(const Grid<float>& field, std::int64_t k, std::int64_t step,
                  std::vector<Radii>& radii, std::vector<std::int64_t>& stack,
                  std::vector<std::int64_t>& members) {
  const VolumeGeometry& g = field.geometry;
  const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  radii.assign(static_cast<std::size_t>(nx * ny), Radii{});
  const float* slice = &field.values[g.linear_index(0, 0, k)];
  const auto slice_at = [&](std::int64_t kk) {
    return kk >= 0 && kk < nz ? &field.values[g.linear_index(0, 0, kk)] : nullptr;
  };
  const float* inner = slice_at(k - step);
  const float* inner2 = slice_at(k - 2 * step);
  for (std::int64_t seed = 0; seed < nx * ny; ++seed) {
    if (slice[seed] <= 0.0F) {
      radii[static_cast<std::size_t>(seed)].last = 0.0F;
      continue;
    }
    if (radii[static_cast<std::size_t>(seed)].last >= 0.0F) continue;
    // Flood the region, then give every member its radii.
    stack.assign(1, seed);
    members.clear();
    radii[static_cast<std::size_t>(seed)].last = 0.0F;
    Radii most{0.0F, 0.0F, 0.0F};
    while (!stack.empty()) {
      const std::int64_t s = stack.back();
      stack.pop_back();
      members.push_back(s);
      most.last = std::max(most.last, slice[s]);
      if (inner != nullptr) most.before = std::max(most.before, inner[s]);
      if (inner2 != nullptr) most.before2 = std::max(most.before2, inner2[s]);
      const std::int64_t x = s % nx, y = s / nx;
      const std::int64_t next[4] = {x > 0 ? s - 1 : -1, x + 1 < nx ? s + 1 : -1,
                                    y > 0 ? s - nx : -1, y + 1 < ny ? s + nx : -1};
      for (const std::int64_t n : next) {
        if (n < 0 || slice[n] <= 0.0F || radii[static_cast<std::size_t>(n)].last >= 0.0F) continue;
        radii[static_cast<std::size_t>(n)].last = 0.0F;
        stack.push_back(n);
      }
    }
    for (const std::int64_t m : members)
      radii[static_cast<std::size_t>(m)] = most;
  }
}

/// How far past the last slice (in slice spacings) the end lies above a sample `rho` from its
/// region's middle. The region's radius over depth D below the end is fitted as an ellipsoid's,
/// r^2 = alpha D - beta D^2, through its radii in the last three slices (exact for the end of an
/// ellipsoid or a ball; beta 0 is a paraboloid); with two, or where that puts the end a spacing
/// or more away, a paraboloid through both outlines; where the region does not narrow towards
/// the end (a flat end), a paraboloid half a spacing high, where such an end lies on average.
double cap_height(double rho, const Radii& r, double dz) {
  const double r1 = r.last, r2 = r.before, r3 = r.before2;
  const auto height = [&](double alpha, double beta, double depth) {
    // The depth below the end where the radius is rho: beta D^2 - alpha D + rho^2 = 0.
    const double disc = alpha * alpha - 4.0 * beta * rho * rho;
    const double d = std::abs(beta) < 1e-12
                         ? rho * rho / alpha
                         : (alpha - std::sqrt(std::max(disc, 0.0))) / (2.0 * beta);
    return (depth - d) / dz;
  };
  if (r2 > r1 && r3 > r2) {
    const double d1 = r2 * r2 - r1 * r1, d2 = r3 * r3 - r2 * r2;
    const double beta = (d1 - d2) / (2.0 * dz * dz);
    const double a = (d1 + beta * dz * dz) / dz;  // alpha - 2 beta h
    // beta h^2 + a h - r1^2 = 0 for the last slice's depth h.
    const double h =
        std::abs(beta) < 1e-12
            ? r1 * r1 / a
            : (-a + std::sqrt(std::max(a * a + 4.0 * beta * r1 * r1, 0.0))) / (2.0 * beta);
    if (a > 0.0 && h > 0.0 && h < dz) {
      return height(a + 2.0 * beta * h, beta, h);
    }
  }
  const double u = rho / r1;
  if (r2 > r1) {
    // A paraboloid (r^2 = 2 R D) through both outlines: its end r1^2 / (r2^2 - r1^2) spacings
    // past the last slice, at most 0.7 (a paraboloid's end lies further than a flatter end's).
    return std::clamp(r1 * r1 / (r2 * r2 - r1 * r1), 0.1, 0.7) * (1.0 - u * u);
  }
  return 0.5 * (1.0 - u * u);
}

}  // namespace

void place_cap_vertices(std::span<Dlfl::Vec3> positions, const Grid<float>& field) {
  const VolumeGeometry& g = field.geometry;
  const std::int64_t nx = g.dims[0], ny = g.dims[1], nz = g.dims[2];
  if (nz < 2 || positions.empty()) return;
  std::vector<std::uint8_t> empty(static_cast<std::size_t>(nz));
  for (std::int64_t k = 0; k < nz; ++k) {
    const float* slice = &field.values[g.linear_index(0, 0, k)];
    empty[static_cast<std::size_t>(k)] =
        std::none_of(slice, slice + nx * ny, [](float v) { return v > 0.0F; }) ? 1 : 0;
  }
  // The vertices on k-edges, by the slice their edge starts at.
  std::vector<std::vector<std::size_t>> on_edge(static_cast<std::size_t>(nz));
  bool any = false;
  for (std::size_t v = 0; v < positions.size(); ++v) {
    const glm::dvec3 c = g.world_to_index(positions[v]);
    if (std::abs(c.x - std::round(c.x)) > 1e-3 || std::abs(c.y - std::round(c.y)) > 1e-3) continue;
    const auto k = static_cast<std::int64_t>(std::floor(c.z));
    if (k < 0 || k + 1 >= nz) continue;
    if (!empty[static_cast<std::size_t>(k)] && !empty[static_cast<std::size_t>(k + 1)]) continue;
    on_edge[static_cast<std::size_t>(k)].push_back(v);
    any = true;
  }
  if (!any) return;
  std::vector<Radii> radii;
  std::vector<std::int64_t> stack, members;
  std::int64_t radii_of = -1;
  for (std::int64_t k = 0; k + 1 < nz; ++k) {
    if (on_edge[static_cast<std::size_t>(k)].empty()) continue;
    // The edge runs from the last slice with inside samples (`last`) into the empty one.
    const bool up = empty[static_cast<std::size_t>(k + 1)] != 0;
    const std::int64_t last = up ? k : k + 1;
    if (empty[static_cast<std::size_t>(last)]) continue;
    if (radii_of != last) {
      region_radii(field, last, up ? 1 : -1, radii, stack, members);
      radii_of = last;
    }
    for (const std::size_t v : on_edge[static_cast<std::size_t>(k)]) {
      glm::dvec3 c = g.world_to_index(positions[v]);
      const std::int64_t i = std::llround(c.x), j = std::llround(c.y);
      const float d = field.at(i, j, last);
      const Radii& r = radii[static_cast<std::size_t>(j * nx + i)];
      if (d <= 0.0F || r.last <= 0.0F) continue;
      const double rho = std::max(static_cast<double>(r.last) - static_cast<double>(d), 0.0);
      // Kept strictly inside the edge, as marching cubes keeps its vertices.
      const double t = std::clamp(cap_height(rho, r, g.spacing.z), 1e-3, 1.0 - 1e-3);
      c.z = static_cast<double>(last) + (up ? t : -t);
      c.x = static_cast<double>(i);
      c.y = static_cast<double>(j);
      positions[v] = g.index_to_world(c);
    }
  }
}

}  // namespace bisturi
