#pragma once
// The solids and the reference of `bisturi tissue indent`: a cube or a sphere as a surface mesh
// (millimetres), and Hertz contact for a rigid spherical probe.

#include <cstddef>

#include "bisturi/scene/oriented_builder.h"

namespace bisturi::cli {

/// A closed cube of side size_mm from (0, 0, 0), n x n quads a face, vertices shared.
PolygonMesh block_mesh(double size_mm, std::size_t n);
/// A sphere of radius_mm from a phantom, its voxels sized for about `vertices` vertices.
PolygonMesh sphere_mesh(double radius_mm, std::size_t vertices);
/// Hertz: the force (N) for an approach `depth` (m) of a rigid sphere of radius probe_r (m) into
/// an elastic body of plane-strain modulus e_star (Pa): a half space (block), or a sphere of
/// radius body_r on a rigid plane (the probe's and the plane's approaches in series).
double hertz_force(double depth, double e_star, double probe_r, double body_r, bool sphere);

}  // namespace bisturi::cli
