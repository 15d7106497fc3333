#pragma once
// Test subjects for the sim tests: a hanging strip, a flat sheet, a sphere (phantom + marching
// cubes), all built with scene's own builders (positions in millimetres).

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/sim/soft_body.h"

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

/// The hanging strip of the sag tests: a one-cell-wide strip of `cells` quads of 10 mm hanging
/// from its anchored top row, with structural springs only (5 N/m), 1 kg/m^2 and drag 20/s.
inline SoftBody hanging_strip(std::size_t cells) {
  Material mat;
  mat.structural_N_per_m = 5.0;
  mat.shear_N_per_m = 0.0;
  mat.bending_N_per_m = 0.0;
  mat.density_kg_per_m3 = 1000.0;
  mat.thickness_m = 0.001;
  mat.bulk_modulus_Pa = 0.0;
  mat.drag_per_s = 20.0;
  SoftBody body(hanging_sheet(1, cells, 10.0), mat);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z > -1e-9) body.set_anchored(VertexId(i), true);
  }
  return body;
}

/// A firm tissue: the probe stays on the cap of sphere(24, 8 mm) it presses.
inline Material firm_material() {
  Material firm;
  firm.structural_N_per_m = 3000.0;
  firm.shear_N_per_m = 1000.0;
  firm.bending_N_per_m = 300.0;
  firm.bulk_modulus_Pa = 20000.0;
  firm.drag_per_s = 20.0;
  return firm;
}

/// The sphere(24, 8 mm) squashed to 80 % of its height about its centre, without drag or spring
/// damping: with no gravity it rings, and backward Euler may only lose its energy.
inline SoftBody squashed_sphere();

/// A closed sphere of radius radius_mm centred at (c, c, c) with c = (dims - 1) / 2 mm.
inline Dlfl sphere(std::int64_t dims, double radius_mm) {
  PhantomOptions o;
  o.shape = PhantomShape::Sphere;
  o.dims = {dims, dims, dims};
  o.spacing = glm::dvec3(1.0);
  o.a = radius_mm;
  return extract_isosurface(make_phantom(o));
}

inline SoftBody squashed_sphere() {
  Material mat;
  mat.drag_per_s = 0.0;
  mat.spring_damping_N_s_per_m = 0.0;
  SoftBody body(sphere(24, 8.0), mat);
  for (auto& p : body.positions())
    p.z = 0.0115 + (p.z - 0.0115) * 0.8;
  return body;
}

}  // namespace bisturi::sim::testing
