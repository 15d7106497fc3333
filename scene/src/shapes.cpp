#include "bisturi/scene/shapes.h"

#include <cmath>
#include <numbers>

namespace bisturi {

namespace {
std::uint32_t u32(std::size_t i) {
  return static_cast<std::uint32_t>(i);
}

/// Quads (or two triangles each) over an (nu x nv) lattice of vertex ids.
template <class Id>
void add_quads(PolygonMesh& m, std::size_t nu, std::size_t nv, bool wrap_u, bool wrap_v,
               bool triangulate, Id id) {
  const std::size_t cu = wrap_u ? nu : nu - 1;
  const std::size_t cv = wrap_v ? nv : nv - 1;
  for (std::size_t j = 0; j < cv; ++j) {
    for (std::size_t i = 0; i < cu; ++i) {
      const std::uint32_t a = id(i, j), b = id((i + 1) % nu, j);
      const std::uint32_t c = id((i + 1) % nu, (j + 1) % nv), d = id(i, (j + 1) % nv);
      if (triangulate) {
        m.add_face({a, b, c});
        m.add_face({a, c, d});
      } else {
        m.add_face({a, b, c, d});
      }
    }
  }
}
}  // namespace

PolygonMesh cube_mesh(const Dlfl::Vec3& o, double s) {
  PolygonMesh m;
  for (int k = 0; k < 8; ++k) {
    m.positions.emplace_back(o.x + s * (k & 1), o.y + s * ((k >> 1) & 1), o.z + s * ((k >> 2) & 1));
  }
  // Vertex k has bits (x, y, z); faces counter-clockwise seen from outside.
  m.add_face({0, 2, 3, 1});  // z = 0
  m.add_face({4, 5, 7, 6});  // z = 1
  m.add_face({0, 1, 5, 4});  // y = 0
  m.add_face({2, 6, 7, 3});  // y = 1
  m.add_face({0, 4, 6, 2});  // x = 0
  m.add_face({1, 3, 7, 5});  // x = 1
  return m;
}

PolygonMesh tetrahedron_mesh() {
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  m.add_face({0, 2, 1});
  m.add_face({0, 1, 3});
  m.add_face({1, 2, 3});
  m.add_face({0, 3, 2});
  return m;
}

PolygonMesh torus_mesh(double major_radius, double minor_radius, std::size_t nu, std::size_t nv,
                       bool triangulate) {
  PolygonMesh m;
  m.positions.reserve(nu * nv);
  for (std::size_t j = 0; j < nv; ++j) {
    const double phi = 2.0 * std::numbers::pi * double(j) / double(nv);
    for (std::size_t i = 0; i < nu; ++i) {
      const double theta = 2.0 * std::numbers::pi * double(i) / double(nu);
      const double r = major_radius + minor_radius * std::cos(phi);
      m.positions.emplace_back(r * std::cos(theta), r * std::sin(theta),
                               minor_radius * std::sin(phi));
    }
  }
  m.indices.reserve(nu * nv * (triangulate ? 6 : 4));
  m.offsets.reserve(nu * nv * (triangulate ? 2 : 1) + 1);
  add_quads(m, nu, nv, true, true, triangulate,
            [nu](std::size_t i, std::size_t j) { return u32(j * nu + i); });
  return m;
}

PolygonMesh grid_mesh(std::size_t nx, std::size_t ny, double cell, bool triangulate) {
  PolygonMesh m;
  for (std::size_t j = 0; j <= ny; ++j) {
    for (std::size_t i = 0; i <= nx; ++i)
      m.positions.emplace_back(cell * double(i), cell * double(j), 0.0);
  }
  add_quads(m, nx + 1, ny + 1, false, false, triangulate,
            [nx](std::size_t i, std::size_t j) { return u32(j * (nx + 1) + i); });
  return m;
}

PolygonMesh tube_mesh(double radius, double length, std::size_t nu, std::size_t nv) {
  PolygonMesh m;
  for (std::size_t j = 0; j <= nv; ++j) {
    for (std::size_t i = 0; i < nu; ++i) {
      const double theta = 2.0 * std::numbers::pi * double(i) / double(nu);
      m.positions.emplace_back(radius * std::cos(theta), radius * std::sin(theta),
                               length * double(j) / double(nv));
    }
  }
  add_quads(m, nu, nv + 1, true, false, false,
            [nu](std::size_t i, std::size_t j) { return u32(j * nu + i); });
  return m;
}

}  // namespace bisturi
