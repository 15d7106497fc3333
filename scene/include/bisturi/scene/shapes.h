#pragma once
// Procedural polygon meshes with known topology, outward-oriented (counter-clockwise seen from
// outside): test subjects, demo solids and benchmark inputs.

#include <cstddef>

#include "bisturi/scene/oriented_builder.h"

namespace bisturi {

/// Axis-aligned cube of 6 quads (closed, genus 0).
PolygonMesh cube_mesh(const Dlfl::Vec3& origin, double size);
/// Tetrahedron on 4 triangles (closed, genus 0).
PolygonMesh tetrahedron_mesh();
/// Torus of nu x nv quads (or 2 nu nv triangles) around the z axis (closed, genus 1).
PolygonMesh torus_mesh(double major_radius, double minor_radius, std::size_t nu, std::size_t nv,
                       bool triangulate);
/// Flat nx x ny grid of quads (or triangles) in the z = 0 plane: a disc with one boundary loop.
PolygonMesh grid_mesh(std::size_t nx, std::size_t ny, double cell, bool triangulate);
/// Open tube of nu x nv quads around the z axis: two boundary loops (a vessel segment).
PolygonMesh tube_mesh(double radius, double length, std::size_t nu, std::size_t nv);

}  // namespace bisturi
