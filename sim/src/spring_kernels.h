#pragma once
// The spring passes over arrays of spring ends, rest lengths and stiffnesses (SoA, padded with
// null springs to a multiple of 4): forces for the right-hand side of the implicit step, and
// elastic energies for the divergence guard.

#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

namespace bisturi::sim {

/// The team splits a spring pass into runs of a multiple of this many springs (the passes take
/// springs four at a time; the split, and so the bits, is what it was with blocks of 64).
constexpr std::size_t kChunk = 64;

/// Spring forces (with the h^2 H v term of the right-hand side divided by h, H each spring's
/// Hessian with its transverse part clamped at zero) accumulated into f, which must start at
/// zero. ns is a multiple of 4; only the first `real` are scattered. With `blocks` (4 floats per
/// spring, ns of them), each spring's block of the solve's matrix h c u u^T + h^2 H as
/// a I + s s^T: (s.x, s.y, s.z, a). `bound`: H = k I and the damping c I instead (the
/// majorising bound, IntegratorOptions::spring_hessian).
double spring_forces(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                     const double* k, std::size_t ns, std::size_t real, const glm::dvec3* x,
                     const glm::dvec3* v, double c, double h, glm::dvec3* f,
                     float* blocks = nullptr, bool bound = false);
/// spring_forces, returning the springs' elastic energy too.
double spring_forces_energy(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                            const double* k, std::size_t ns, std::size_t real, const glm::dvec3* x,
                            const glm::dvec3* v, double c, double h, glm::dvec3* f,
                            float* blocks = nullptr, bool bound = false);
/// The springs' elastic energy at x (ns a multiple of 4, null springs add nothing).
double spring_energy(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                     const double* k, std::size_t ns, const glm::dvec3* x);

}  // namespace bisturi::sim
