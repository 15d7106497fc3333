#pragma once
// The trilinear hexahedron on an axis-aligned box, for linear isotropic elasticity with
// selective reduced integration (Hughes, "The Finite Element Method", section 4.4): the shear
// part with 2x2x2 Gauss points, the volumetric part with one point at the centre, so a nearly
// incompressible tissue (nu = 0.45 to 0.49) does not lock. Corners are numbered as in
// HexLattice: corner c is at (c & 1, (c >> 1) & 1, (c >> 2) & 1) times the box's sides.

#include <array>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

namespace bisturi::sim {

/// The element's 8 x 8 blocks of 3 x 3: K[i][j] maps corner j's displacement to the force on
/// corner i (the restoring force is -K u).
using HexStiffness = std::array<std::array<glm::dmat3, 8>, 8>;

/// The stiffness of a box with sides h (metres) of a material with Lame parameters mu and
/// lambda (Pa), scaled by `scale` (the cell's inside share).
void box_stiffness(const glm::dvec3& h, double mu, double lambda, double scale, HexStiffness& k);

/// The shape functions' gradients at the box's centre (1/m): the deformation gradient of the
/// element is sum_i x_i (x) grad_i.
std::array<glm::dvec3, 8> centre_gradients(const glm::dvec3& h);

/// The shape functions' gradients (1/m) at the 2 x 2 x 2 Gauss points: [point][corner].
std::array<std::array<glm::dvec3, 8>, 8> gauss_gradients(const glm::dvec3& h);

/// The first Piola-Kirchhoff stress (Pa) of compressible neo-Hookean tissue (CalculiX's
/// *HYPERELASTIC, NEO HOOKE: W = C10 (J^-2/3 I1 - 3) + (J - 1)^2 / D1, C10 = mu / 2,
/// D1 = 2 / K), split as selective reduced integration wants it: the isochoric part for the Gauss
/// points, the volumetric part for the centre. A collapsed or inverted F (J <= 0) gives the
/// stress of a J of 0.01, pushing it back open.
glm::dmat3 neo_hookean_isochoric_stress(const glm::dmat3& f, double mu);
glm::dmat3 neo_hookean_volumetric_stress(const glm::dmat3& f, double bulk);

/// The rotation of F's polar decomposition F = R S (F not inverted; a degenerate F gives the
/// identity).
glm::dmat3 polar_rotation(const glm::dmat3& f);

}  // namespace bisturi::sim
