// The spring passes (spring_kernels.h).

#include "spring_kernels.h"

#include <algorithm>
#include <cmath>
#include <cstring>

#include "hot_loop.h"

namespace bisturi::sim {
namespace {

/// Four doubles: one per spring of a group of four (lane l is spring s + l).
typedef double V4 __attribute__((vector_size(32)));

/// The four springs' end differences d = x_b - x_a (and the velocities' when Velocities).
template <bool Velocities>
BISTURI_INLINE void gather(const std::uint32_t* a, const std::uint32_t* b, const glm::dvec3* x,
                           const glm::dvec3* v, V4 (&d)[3], V4 (&dv)[3]) {
  const glm::dvec3 x0 = x[b[0]] - x[a[0]], x1 = x[b[1]] - x[a[1]], x2 = x[b[2]] - x[a[2]],
                   x3 = x[b[3]] - x[a[3]];
  d[0] = V4{x0.x, x1.x, x2.x, x3.x};
  d[1] = V4{x0.y, x1.y, x2.y, x3.y};
  d[2] = V4{x0.z, x1.z, x2.z, x3.z};
  if constexpr (Velocities) {
    const glm::dvec3 v0 = v[b[0]] - v[a[0]], v1 = v[b[1]] - v[a[1]], v2 = v[b[2]] - v[a[2]],
                     v3 = v[b[3]] - v[a[3]];
    dv[0] = V4{v0.x, v1.x, v2.x, v3.x};
    dv[1] = V4{v0.y, v1.y, v2.y, v3.y};
    dv[2] = V4{v0.z, v1.z, v2.z, v3.z};
  }
}

// Vectors go through references, not return values: a V4 returned by value changes the ABI of
// the baseline clone (GCC's -Wpsabi), even inlined.
BISTURI_INLINE void length(const V4 (&d)[3], V4& len) {
  const V4 len2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2];
  len = V4{std::sqrt(len2[0]), std::sqrt(len2[1]), std::sqrt(len2[2]), std::sqrt(len2[3])};
}

BISTURI_INLINE void load4(const double* p, V4& out) {
  std::memcpy(&out, p, sizeof(V4));
}

/// Four springs' geometry at x: end differences, lengths, stretches and stiffnesses (and the
/// velocity differences when Velocities).
template <bool Velocities>
struct SpringGroup {
  V4 d[3] = {}, dv[3] = {}, k = {}, len = {}, stretch = {};
  BISTURI_INLINE SpringGroup(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                             const double* k4, const glm::dvec3* x, const glm::dvec3* v) {
    gather<Velocities>(a, b, x, v, d, dv);
    load4(k4, k);
    V4 rs;
    load4(rest, rs);
    length(d, len);
    stretch = len - rs;
  }
};

/// Spring forces (with the h^2 H v term of the right-hand side divided by h) accumulated into
/// f, which must start at zero; returns the springs' elastic energy when Energy is set. ns is a
/// multiple of 4 (null springs pad the arrays); only the first `real` are scattered. Four
/// springs at a time in registers: gathered, computed as one vector each (sqrt and division
/// four or two at a time), scattered in spring order.
///
/// H is the spring's Hessian with its transverse eigenvalue clamped at zero (the projection of
/// the 3 x 3 block onto the positive semi-definite ones): k u u^T + w (I - u u^T), w = k max(0,
/// 1 - L0 / L). With `blocks`, each spring's block of the solve's matrix, h c u u^T + h^2 H =
/// a I + s s^T, is written as four floats (s, a): a = h^2 w, s = sqrt(h c + h^2 (k - w)) u.
/// With `bound`, H is the bound k I and the damping's block c I (a = h^2 k + h c, s = 0).
template <bool Energy>
BISTURI_INLINE double spring_pass_impl(const std::uint32_t* a, const std::uint32_t* b,
                                       const double* rest, const double* k, std::size_t ns,
                                       std::size_t real, const glm::dvec3* x, const glm::dvec3* v,
                                       double c, double h, glm::dvec3* f, float* blocks,
                                       bool bound) {
  const V4 one = {1.0, 1.0, 1.0, 1.0}, zero = {0.0, 0.0, 0.0, 0.0};
  V4 e4 = zero;
  for (std::size_t s = 0; s < ns; s += 4) {
    const SpringGroup<true> g(a + s, b + s, rest + s, k + s, x, v);
    const V4(&d)[3] = g.d;
    const V4(&dv)[3] = g.dv;
    const V4 &ks = g.k, &stretch = g.stretch;
    // Branch-free 1 / len (0 for a null spring).
    const V4 ok = g.len > 1e-12 ? one : zero;
    const V4 inv = ok / (g.len + (one - ok));
    const V4 rel = (d[0] * dv[0] + d[1] * dv[1] + d[2] * dv[2]) * inv;  // u . vrel
    // The clamped transverse stiffness k max(0, 1 - L0 / L) = k max(0, stretch / L).
    const V4 ratio = stretch * inv;
    // The bound k I instead: the transverse stiffness k as well.
    const V4 wt = bound ? ks : ks * (ratio > 0.0 ? ratio : zero);
    // (k stretch + c u . vrel + h (k - w) u . vrel) u, with u = d / len, written on d (one scale
    // for all three), and h w vrel across: h f + h^2 H v, divided by h.
    const V4 along = (ks * stretch + (c + h * (ks - wt)) * rel) * inv;
    if constexpr (Energy) e4 += 0.5 * ks * stretch * stretch;
    const V4 hw = h * wt;
    const V4 fx = along * d[0] + hw * dv[0], fy = along * d[1] + hw * dv[1],
             fz = along * d[2] + hw * dv[2];
    if (blocks != nullptr) {
      // The bound's damping is c I as well: all of the block is a.
      const V4 axial = bound ? zero : h * c + h * h * (ks - wt);
      const V4 root = {std::sqrt(axial[0]), std::sqrt(axial[1]), std::sqrt(axial[2]),
                       std::sqrt(axial[3])};
      const V4 scale = root * inv, diag = h * h * wt + (bound ? h * c * ok : zero);
      for (std::size_t l = 0; l < 4; ++l) {
        float* out = blocks + 4 * (s + l);
        out[0] = static_cast<float>(scale[l] * d[0][l]);
        out[1] = static_cast<float>(scale[l] * d[1][l]);
        out[2] = static_cast<float>(scale[l] * d[2][l]);
        out[3] = static_cast<float>(diag[l]);
      }
    }
    const std::size_t m = s < real ? std::min<std::size_t>(4, real - s) : 0;
    for (std::size_t l = 0; l < m; ++l) {
      glm::dvec3& fa = f[a[s + l]];
      glm::dvec3& fb = f[b[s + l]];
      fa.x += fx[l];
      fa.y += fy[l];
      fa.z += fz[l];
      fb.x -= fx[l];
      fb.y -= fy[l];
      fb.z -= fz[l];
    }
  }
  return (e4[0] + e4[1]) + (e4[2] + e4[3]);
}

}  // namespace

BISTURI_HOT double spring_forces(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                                 const double* k, std::size_t ns, std::size_t real,
                                 const glm::dvec3* x, const glm::dvec3* v, double c, double h,
                                 glm::dvec3* f, float* blocks, bool bound) {
  return spring_pass_impl<false>(a, b, rest, k, ns, real, x, v, c, h, f, blocks, bound);
}

BISTURI_HOT double spring_forces_energy(const std::uint32_t* a, const std::uint32_t* b,
                                        const double* rest, const double* k, std::size_t ns,
                                        std::size_t real, const glm::dvec3* x, const glm::dvec3* v,
                                        double c, double h, glm::dvec3* f, float* blocks,
                                        bool bound) {
  return spring_pass_impl<true>(a, b, rest, k, ns, real, x, v, c, h, f, blocks, bound);
}

/// The springs' elastic energy at x (ns a multiple of 4, null springs add nothing).
BISTURI_HOT double spring_energy(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                                 const double* k, std::size_t ns, const glm::dvec3* x) {
  V4 e4 = {0.0, 0.0, 0.0, 0.0};
  for (std::size_t s = 0; s < ns; s += 4) {
    const SpringGroup<false> g(a + s, b + s, rest + s, k + s, x, nullptr);
    e4 += 0.5 * g.k * g.stretch * g.stretch;
  }
  return (e4[0] + e4[1]) + (e4[2] + e4[3]);
}

}  // namespace bisturi::sim
