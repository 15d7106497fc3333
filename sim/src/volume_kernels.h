#pragma once
// The triangle passes of the volume term: the enclosed volume and its gradient over a closed
// surface's triangles (index triples).

#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

namespace bisturi::sim {

/// Adds the area vector (x1 - x0) x (x2 - x0) of each triangle in [first, last) to the gradient
/// of its three corners (6 dV/dx_i, summed over a closed fan); returns 6 V of those triangles
/// (sum of x0 . area vector).
double volume_gradient(const std::uint32_t* indices, std::size_t first, std::size_t last,
                       const glm::dvec3* x, glm::dvec3* grad);
/// 6 V of the triangles in [first, last): the sum of x0 . (x1 x x2) (SoftBody::volume_m3).
double six_volume(const std::uint32_t* indices, std::size_t first, std::size_t last,
                  const glm::dvec3* x);

/// volume_gradient over the triangles listed in tris[0..count) instead of a range.
double volume_gradient_of(const std::uint32_t* indices, const std::uint32_t* tris,
                          std::size_t count, const glm::dvec3* x, glm::dvec3* grad);
/// Each listed triangle's 6 V (x0 . (x1 x x2)) into out[triangle].
void six_volumes_of(const std::uint32_t* indices, const std::uint32_t* tris, std::size_t count,
                    const glm::dvec3* x, double* out);

}  // namespace bisturi::sim
