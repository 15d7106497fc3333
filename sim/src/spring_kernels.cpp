// The spring passes (spring_kernels.h).

#include "spring_kernels.h"

#include <algorithm>
#include <cmath>

#include "hot_loop.h"

namespace bisturi::sim {
namespace {

/// Spring forces (with the h^2 H v term of the right-hand side divided by h) accumulated into
/// f, which must start at zero; returns the springs' elastic energy when Energy is set. ns is a
/// multiple of 4 (null springs pad the arrays); only the first `real` are scattered.
template <bool Energy>
BISTURI_INLINE double spring_pass_impl(const std::uint32_t* a, const std::uint32_t* b,
                                       const double* rest, const double* k, std::size_t ns,
                                       std::size_t real, const glm::dvec3* x, const glm::dvec3* v,
                                       double c, double h, glm::dvec3* f) {
  double dx[kChunk], dy[kChunk], dz[kChunk], vx[kChunk], vy[kChunk], vz[kChunk], along[kChunk],
      energy[kChunk];
  double e4[4] = {0.0, 0.0, 0.0, 0.0};
  for (std::size_t s0 = 0; s0 < ns; s0 += kChunk) {
    const std::size_t m = std::min(kChunk, ns - s0);
    for (std::size_t j = 0; j < m; ++j) {
      const glm::dvec3 xa = x[a[s0 + j]], xb = x[b[s0 + j]];
      const glm::dvec3 va = v[a[s0 + j]], vb = v[b[s0 + j]];
      dx[j] = xb.x - xa.x;
      dy[j] = xb.y - xa.y;
      dz[j] = xb.z - xa.z;
      vx[j] = vb.x - va.x;
      vy[j] = vb.y - va.y;
      vz[j] = vb.z - va.z;
    }
    const double* rs = rest + s0;
    const double* ks = k + s0;
    for (std::size_t q = 0; q < m; ++q) {
      const double len = std::sqrt(dx[q] * dx[q] + dy[q] * dy[q] + dz[q] * dz[q]);
      // Branch-free 1 / len (0 for a null spring), so that the loop vectorises.
      const double ok = len > 1e-12 ? 1.0 : 0.0;
      const double inv = ok / (len + (1.0 - ok));
      const double stretch = len - rs[q];
      // (k stretch + c u . vrel) u with u = d / len, written on d: one scale for all three.
      along[q] =
          (ks[q] * stretch + c * (dx[q] * vx[q] + dy[q] * vy[q] + dz[q] * vz[q]) * inv) * inv;
      if constexpr (Energy) energy[q] = 0.5 * ks[q] * stretch * stretch;
    }
    if constexpr (Energy) {
      for (std::size_t j = 0; j < m; j += 4) {
        for (std::size_t l = 0; l < 4; ++l)
          e4[l] += energy[j + l];
      }
    }
    const std::size_t mr = s0 < real ? std::min(m, real - s0) : 0;
    for (std::size_t j = 0; j < mr; ++j) {
      const double hk = h * k[s0 + j];  // h f + h^2 H v, divided by h below
      const double fx = along[j] * dx[j] + hk * vx[j], fy = along[j] * dy[j] + hk * vy[j],
                   fz = along[j] * dz[j] + hk * vz[j];
      glm::dvec3& fa = f[a[s0 + j]];
      glm::dvec3& fb = f[b[s0 + j]];
      fa.x += fx;
      fa.y += fy;
      fa.z += fz;
      fb.x -= fx;
      fb.y -= fy;
      fb.z -= fz;
    }
  }
  return (e4[0] + e4[1]) + (e4[2] + e4[3]);
}

}  // namespace

BISTURI_HOT double spring_forces(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                                 const double* k, std::size_t ns, std::size_t real,
                                 const glm::dvec3* x, const glm::dvec3* v, double c, double h,
                                 glm::dvec3* f) {
  return spring_pass_impl<false>(a, b, rest, k, ns, real, x, v, c, h, f);
}

BISTURI_HOT double spring_forces_energy(const std::uint32_t* a, const std::uint32_t* b,
                                        const double* rest, const double* k, std::size_t ns,
                                        std::size_t real, const glm::dvec3* x, const glm::dvec3* v,
                                        double c, double h, glm::dvec3* f) {
  return spring_pass_impl<true>(a, b, rest, k, ns, real, x, v, c, h, f);
}

/// The springs' elastic energy at x (ns a multiple of 4, null springs add nothing).
BISTURI_HOT double spring_energy(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                                 const double* k, std::size_t ns, const glm::dvec3* x) {
  double len2[kChunk];
  double e4[4] = {0.0, 0.0, 0.0, 0.0};
  for (std::size_t s0 = 0; s0 < ns; s0 += kChunk) {
    const std::size_t m = std::min(kChunk, ns - s0);
    for (std::size_t j = 0; j < m; ++j) {
      const glm::dvec3 d = x[b[s0 + j]] - x[a[s0 + j]];
      len2[j] = d.x * d.x + d.y * d.y + d.z * d.z;
    }
    for (std::size_t j = 0; j < m; j += 4) {
      for (std::size_t l = 0; l < 4; ++l) {
        const double stretch = std::sqrt(len2[j + l]) - rest[s0 + j + l];
        e4[l] += 0.5 * k[s0 + j + l] * stretch * stretch;
      }
    }
  }
  return (e4[0] + e4[1]) + (e4[2] + e4[3]);
}

}  // namespace bisturi::sim
