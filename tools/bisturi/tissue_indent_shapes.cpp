#include "tissue_indent_shapes.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"

namespace bisturi::cli {

namespace {

/// Hertz: the approach of a rigid sphere of radius r pressed by force f onto an elastic body of
/// plane-strain modulus e_star with radius of curvature body_r (infinite: a half space).
double hertz_approach(double f, double e_star, double r, double body_r) {
  const double reff = std::isinf(body_r) ? r : r * body_r / (r + body_r);
  return std::cbrt(9.0 * f * f / (16.0 * e_star * e_star * reff));
}

}  // namespace

/// A closed cube of side size_mm from (0, 0, 0), n x n quads a face, vertices shared.
PolygonMesh block_mesh(double size_mm, std::size_t n) {
  PolygonMesh m;
  const std::size_t side = n + 1;
  // Lattice points on the cube's surface, numbered once.
  std::vector<std::uint32_t> index(side * side * side, UINT32_MAX);
  auto at = [&](std::size_t i, std::size_t j, std::size_t k) {
    std::uint32_t& id = index[(i * side + j) * side + k];
    if (id == UINT32_MAX) {
      id = static_cast<std::uint32_t>(m.positions.size());
      const double h = size_mm / double(n);
      m.positions.push_back(Dlfl::Vec3(double(i) * h, double(j) * h, double(k) * h));
    }
    return id;
  };
  // Each face: its two in-plane axes (u, v) and the fixed coordinate; winding outward.
  for (std::size_t axis = 0; axis < 3; ++axis) {
    for (std::size_t end = 0; end < 2; ++end) {
      const std::size_t fixed = end == 0 ? 0 : n;
      const std::size_t u = (axis + 1) % 3, v = (axis + 2) % 3;
      for (std::size_t a = 0; a < n; ++a) {
        for (std::size_t b = 0; b < n; ++b) {
          std::uint32_t q[4];
          const std::size_t corners[4][2] = {{a, b}, {a + 1, b}, {a + 1, b + 1}, {a, b + 1}};
          for (std::size_t c = 0; c < 4; ++c) {
            std::size_t p[3];
            p[axis] = fixed;
            p[u] = corners[c][0];
            p[v] = corners[c][1];
            q[c] = at(p[0], p[1], p[2]);
          }
          if (end == 0) {
            m.add_face({q[0], q[3], q[2], q[1]});
          } else {
            m.add_face({q[0], q[1], q[2], q[3]});
          }
        }
      }
    }
  }
  return m;
}

/// A sphere of radius_mm from a phantom, its voxels sized for about `vertices` vertices
/// (marching cubes gives about 19 (r / spacing)^2).
PolygonMesh sphere_mesh(double radius_mm, std::size_t vertices) {
  PhantomOptions o;
  o.shape = PhantomShape::Sphere;
  const double spacing = radius_mm * std::sqrt(19.0 / double(std::max<std::size_t>(vertices, 50)));
  const auto dims = static_cast<std::int64_t>(std::ceil(2.0 * radius_mm / spacing)) + 6;
  o.dims = {dims, dims, dims};
  o.spacing = glm::dvec3(spacing);
  o.a = radius_mm;
  return extract_isosurface_mesh(make_phantom(o));
}

/// The force for an approach `depth` (m) of the probe: at the probe alone (block), or at the
/// probe and at the plane in series (sphere), by bisection on the approach.
double hertz_force(double depth, double e_star, double probe_r, double body_r, bool sphere) {
  if (depth <= 0.0) return 0.0;
  auto approach = [&](double f) {
    double a = hertz_approach(f, e_star, probe_r, body_r);
    if (sphere) a += hertz_approach(f, e_star, 1e300, body_r);  // the plane: R = body radius
    return a;
  };
  double lo = 0.0, hi = 1.0;
  while (approach(hi) < depth && hi < 1e9)
    hi *= 2.0;
  for (int i = 0; i < 100; ++i) {
    const double mid = 0.5 * (lo + hi);
    (approach(mid) < depth ? lo : hi) = mid;
  }
  return 0.5 * (lo + hi);
}

}  // namespace bisturi::cli
