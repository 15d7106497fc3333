// The triangle passes of the volume term (volume_kernels.h).

#include "volume_kernels.h"

#include <initializer_list>

#include <glm/geometric.hpp>

namespace bisturi::sim {

namespace {

/// One triangle's area vector added to its corners' gradient; returns its 6 V.
inline double add_area_vector(const std::uint32_t* indices, std::size_t t, const double* xs,
                              double* gs) {
  // Plain scalars: with glm temporaries GCC spilled the cross product to the stack as one
  // 16-byte and one 8-byte store and read it back across both (a failed store-to-load
  // forward, about a fifth of the substep's time on the Zen 1 machine).
  const std::size_t i0 = 3 * std::size_t(indices[3 * t]), i1 = 3 * std::size_t(indices[3 * t + 1]),
                    i2 = 3 * std::size_t(indices[3 * t + 2]);
  const double ax = xs[i1] - xs[i0], ay = xs[i1 + 1] - xs[i0 + 1], az = xs[i1 + 2] - xs[i0 + 2];
  const double bx = xs[i2] - xs[i0], by = xs[i2 + 1] - xs[i0 + 1], bz = xs[i2 + 2] - xs[i0 + 2];
  const double nx = ay * bz - az * by, ny = az * bx - ax * bz, nz = ax * by - ay * bx;
  const double six_v = xs[i0] * nx + xs[i0 + 1] * ny + xs[i0 + 2] * nz;
  for (const std::size_t i : {i0, i1, i2}) {
    gs[i] += nx;
    gs[i + 1] += ny;
    gs[i + 2] += nz;
  }
  return six_v;
}

double triangle_six_volume(const std::uint32_t* indices, std::size_t t, const glm::dvec3* x) {
  const glm::dvec3& a = x[indices[3 * t]];
  const glm::dvec3& b = x[indices[3 * t + 1]];
  const glm::dvec3& c = x[indices[3 * t + 2]];
  return glm::dot(a, glm::cross(b, c));
}

}  // namespace

double volume_gradient(const std::uint32_t* indices, std::size_t first, std::size_t last,
                       const glm::dvec3* x, glm::dvec3* grad) {
  static_assert(sizeof(glm::dvec3) == 3 * sizeof(double));
  double six_v = 0.0;
  for (std::size_t t = first; t < last; ++t)
    six_v += add_area_vector(indices, t, &x[0].x, &grad[0].x);
  return six_v;
}

double volume_gradient_of(const std::uint32_t* indices, const std::uint32_t* tris,
                          std::size_t count, const glm::dvec3* x, glm::dvec3* grad) {
  double six_v = 0.0;
  for (std::size_t k = 0; k < count; ++k)
    six_v += add_area_vector(indices, tris[k], &x[0].x, &grad[0].x);
  return six_v;
}

double six_volume(const std::uint32_t* indices, std::size_t first, std::size_t last,
                  const glm::dvec3* x) {
  double six_v = 0.0;
  for (std::size_t t = first; t < last; ++t)
    six_v += triangle_six_volume(indices, t, x);
  return six_v;
}

void six_volumes_of(const std::uint32_t* indices, const std::uint32_t* tris, std::size_t count,
                    const glm::dvec3* x, double* out) {
  for (std::size_t k = 0; k < count; ++k)
    out[tris[k]] = triangle_six_volume(indices, tris[k], x);
}

}  // namespace bisturi::sim
