// The triangle passes of the volume term (volume_kernels.h).

#include "volume_kernels.h"

#include <initializer_list>

#include <glm/geometric.hpp>

namespace bisturi::sim {

double volume_gradient(const std::uint32_t* indices, std::size_t first, std::size_t last,
                       const glm::dvec3* x, glm::dvec3* grad) {
  // Plain scalars: with glm temporaries GCC spilled the cross product to the stack as one
  // 16-byte and one 8-byte store and read it back across both (a failed store-to-load
  // forward, about a fifth of the substep's time on the Zen 1 machine).
  static_assert(sizeof(glm::dvec3) == 3 * sizeof(double));
  const double* xs = &x[0].x;
  double* gs = &grad[0].x;
  double six_v = 0.0;
  for (std::size_t t = first; t < last; ++t) {
    const std::size_t i0 = 3 * std::size_t(indices[3 * t]),
                      i1 = 3 * std::size_t(indices[3 * t + 1]),
                      i2 = 3 * std::size_t(indices[3 * t + 2]);
    const double ax = xs[i1] - xs[i0], ay = xs[i1 + 1] - xs[i0 + 1], az = xs[i1 + 2] - xs[i0 + 2];
    const double bx = xs[i2] - xs[i0], by = xs[i2 + 1] - xs[i0 + 1], bz = xs[i2 + 2] - xs[i0 + 2];
    const double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
    six_v += xs[i0] * nx + xs[i0 + 1] * ny + xs[i0 + 2] * nz;
    for (const std::size_t i : {i0, i1, i2}) {
      gs[i] += nx;
      gs[i + 1] += ny;
      gs[i + 2] += nz;
    }
  }
  return six_v;
}

double six_volume(const std::uint32_t* indices, std::size_t first, std::size_t last,
                  const glm::dvec3* x) {
  double six_v = 0.0;
  for (std::size_t t = first; t < last; ++t) {
    const glm::dvec3& a = x[indices[3 * t]];
    const glm::dvec3& b = x[indices[3 * t + 1]];
    const glm::dvec3& c = x[indices[3 * t + 2]];
    six_v += glm::dot(a, glm::cross(b, c));
  }
  return six_v;
}

}  // namespace bisturi::sim
