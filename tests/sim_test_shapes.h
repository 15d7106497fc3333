#pragma once
// Test subjects for the sim tests: a hanging strip, a flat sheet, a sphere (phantom + marching
// cubes), all built with scene's own builders (positions in millimetres).

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"

namespace bisturi::sim::testing {

/// A flat nx x ny sheet of quads (cell in mm) in the z = 0 plane.
inline Dlfl sheet(std::size_t nx, std::size_t ny, double cell_mm) {
  return build_oriented_manifold(grid_mesh(nx, ny, cell_mm, false));
}

/// The same sheet standing in the x-z plane, its first row at z = 0 and the rest below.
inline Dlfl hanging_sheet(std::size_t nx, std::size_t ny, double cell_mm) {
  PolygonMesh m = grid_mesh(nx, ny, cell_mm, false);
  for (auto& p : m.positions)
    p = Dlfl::Vec3(p.x, 0.0, -p.y);
  return build_oriented_manifold(m);
}

/// A closed sphere of radius radius_mm centred at (c, c, c) with c = (dims - 1) / 2 mm.
inline Dlfl sphere(std::int64_t dims, double radius_mm) {
  PhantomOptions o;
  o.shape = PhantomShape::Sphere;
  o.dims = {dims, dims, dims};
  o.spacing = glm::dvec3(1.0);
  o.a = radius_mm;
  return extract_isosurface(make_phantom(o));
}

}  // namespace bisturi::sim::testing
