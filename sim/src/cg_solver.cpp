// The conjugate gradient of the implicit step (cg_solver.h).

#include "cg_solver.h"

#include <algorithm>
#include <array>
#include <cstring>

#include "hot_loop.h"

namespace bisturi::sim {
namespace {

/// One free vertex's four lanes as a GCC/Clang vector (SSE for float, two SSE or one AVX
/// register for double) and its double-precision counterpart for the reductions. Loads and
/// stores go through memcpy (no alignment assumed, no aliasing questions).
template <class T>
struct Lanes;
template <>
struct Lanes<float> {
  typedef float V __attribute__((vector_size(16)));
};
template <>
struct Lanes<double> {
  typedef double V __attribute__((vector_size(32)));
};
typedef double D4 __attribute__((vector_size(32)));

/// out = A in; returns in . out. A = S + L with S the diagonal part that is not a free
/// neighbour's weight and L the weighted Laplacian over the free neighbours, applied as
/// sum w (in_i - in_j): differences of neighbours instead of the diagonal minus a sum of
/// neighbours, so that float keeps its precision where the two nearly cancel (smooth vectors).
template <class T>
BISTURI_INLINE void product_rows(const CgData<T>& d, const T* in, T* out, std::size_t first,
                                 std::size_t last, D4& acc) {
  using V = typename Lanes<T>::V;
  acc = D4{0.0, 0.0, 0.0, 0.0};
  const std::uint32_t* row = d.row;
  const std::uint32_t* col = d.col;
  for (std::size_t i = first; i < last; ++i) {
    V pi, s;
    std::memcpy(&pi, in + 4 * i, sizeof(V));
    s = pi * d.self[i];
    const std::uint32_t end = row[i + 1];
    for (std::uint32_t e = row[i]; e < end; e += 2) {
      const std::uint32_t c0 = col[e], c1 = col[e + 1];
      V n0, n1;
      std::memcpy(&n0, in + 4 * std::size_t(c0 & kIndexMask), sizeof(V));
      std::memcpy(&n1, in + 4 * std::size_t(c1 & kIndexMask), sizeof(V));
      s += (pi - n0) * d.w[c0 >> 30] + (pi - n1) * d.w[c1 >> 30];
    }
    std::memcpy(out + 4 * i, &s, sizeof(V));
    acc += __builtin_convertvector(pi * s, D4);
  }
}

template <class T>
BISTURI_INLINE double product(const CgData<T>& d, const T* in, T* out) {
  double in_out = 0.0;
  if (d.team == nullptr) {
    D4 acc;
    product_rows(d, in, out, 0, d.nf, acc);
    in_out = (acc[0] + acc[1]) + (acc[2] + acc[3]);
  } else {
    // Each member its rows and its partial sum, added in member order.
    std::array<D4, kMaxThreads> parts;
    struct Job {
      const CgData<T>& d;
      const T* in;
      T* out;
      std::array<D4, kMaxThreads>& parts;
      void operator()(unsigned t) const {
        product_rows(d, in, out, d.part[t], d.part[t + 1], parts[t]);
      }
    } job{d, in, out, parts};
    d.team->run([&job](unsigned t) { job(t); });
    for (unsigned t = 0; t < d.team->size(); ++t)
      in_out += (parts[t][0] + parts[t][1]) + (parts[t][2] + parts[t][3]);
  }
  for (std::size_t c = 0; c < d.contacts; ++c) {
    const double* ct = d.contact + 5 * c;
    const std::size_t ci = static_cast<std::size_t>(ct[0]);
    const T* pi = in + 4 * ci;
    const double np = ct[1] * double(pi[0]) + ct[2] * double(pi[1]) + ct[3] * double(pi[2]);
    const double kn = ct[4] * np;
    for (std::size_t l = 0; l < 3; ++l)
      out[4 * ci + l] = static_cast<T>(double(out[4 * ci + l]) + kn * ct[1 + l]);
    in_out += kn * np;
  }
  return in_out;
}

/// The coarse correction: xc = (P^T A P)^-1 rc by the packed Cholesky factor (forward, then
/// backward by columns so both sweeps read rows); returns rc . xc.
template <class T>
BISTURI_INLINE double coarse_solve(const CgData<T>& d) {
  using V = typename Lanes<T>::V;
  constexpr std::size_t kV = sizeof(V);
  const std::size_t nc = d.nc;
  const T* L = d.chol;
  T* x = d.xc;
  for (std::size_t i = 0; i < nc; ++i) {
    const T* li = L + i * (i + 1) / 2;
    V s;
    std::memcpy(&s, d.rc + 4 * i, kV);
    for (std::size_t j = 0; j < i; ++j) {
      V xj;
      std::memcpy(&xj, x + 4 * j, kV);
      s -= xj * li[j];
    }
    s *= li[i];
    std::memcpy(x + 4 * i, &s, kV);
  }
  for (std::size_t i = nc; i-- > 0;) {
    const T* li = L + i * (i + 1) / 2;
    V xi;
    std::memcpy(&xi, x + 4 * i, kV);
    xi *= li[i];
    std::memcpy(x + 4 * i, &xi, kV);
    for (std::size_t j = 0; j < i; ++j) {
      V xj;
      std::memcpy(&xj, x + 4 * j, kV);
      xj -= xi * li[j];
      std::memcpy(x + 4 * j, &xj, kV);
    }
  }
  D4 acc = {};
  for (std::size_t i = 0; i < nc; ++i) {
    V a, b;
    std::memcpy(&a, d.rc + 4 * i, kV);
    std::memcpy(&b, x + 4 * i, kV);
    acc += __builtin_convertvector(a * b, D4);
  }
  return (acc[0] + acc[1]) + (acc[2] + acc[3]);
}

/// Jacobi-preconditioned CG from the start value in d.dv; returns the iterations, r2 the last
/// squared residual. Three passes per iteration: A p (with p . A p), the update of dv and r (with
/// r . z and r . r), the new direction.
template <class T>
BISTURI_INLINE int cg_impl(const CgData<T>& d, int max_iterations, double tol2, double& r2) {
  using V = typename Lanes<T>::V;
  constexpr std::size_t kV = sizeof(V);
  const std::size_t nf = d.nf;
  const bool two_level = d.nc > 0;
  T* r = d.r;
  T* p = d.p;
  T* ap = d.ap;
  T* dv = d.dv;
  const T* inv = d.inv;
  const std::uint32_t* agg = d.agg;
  auto sum = [](const D4& a) { return (a[0] + a[1]) + (a[2] + a[3]); };
  // z = inv r + P xc is never stored: r . z is r . inv r plus rc . xc, and the direction pass
  // adds P xc itself.
  auto add_restricted = [&](std::size_t i, const V& ri) {
    V c;
    std::memcpy(&c, d.rc + 4 * agg[i], kV);
    c += ri;
    std::memcpy(d.rc + 4 * agg[i], &c, kV);
  };
  double rz = 0.0;
  product(d, dv, ap);
  {
    if (two_level) std::fill(d.rc, d.rc + 4 * d.nc, T(0));
    D4 rz4 = {}, r24 = {};
    for (std::size_t i = 0; i < nf; ++i) {
      V bi, api, invi;
      std::memcpy(&bi, d.b + 4 * i, kV);
      std::memcpy(&api, ap + 4 * i, kV);
      std::memcpy(&invi, inv + 4 * i, kV);
      const V ri = bi - api, zi = ri * invi;
      std::memcpy(r + 4 * i, &ri, kV);
      std::memcpy(p + 4 * i, &zi, kV);
      rz4 += __builtin_convertvector(ri * zi, D4);
      r24 += __builtin_convertvector(ri * ri, D4);
      if (two_level) add_restricted(i, ri);
    }
    rz = sum(rz4);
    r2 = sum(r24);
    if (two_level) {
      rz += coarse_solve(d);
      for (std::size_t i = 0; i < nf; ++i) {
        V pi, xi;
        std::memcpy(&pi, p + 4 * i, kV);
        std::memcpy(&xi, d.xc + 4 * agg[i], kV);
        pi += xi;
        std::memcpy(p + 4 * i, &pi, kV);
      }
    }
  }
  int it = 0;
  while (it < max_iterations && r2 > tol2) {  // tol2 starts the solve, d.stop2 ends it
    const double pap = product(d, p, ap);
    if (!(pap > 0.0)) break;
    const T alpha = static_cast<T>(rz / pap);
    if (two_level) std::fill(d.rc, d.rc + 4 * d.nc, T(0));
    D4 rz4 = {}, r24 = {};
    for (std::size_t i = 0; i < nf; ++i) {
      V dvi, ri, pi, api, invi;
      std::memcpy(&dvi, dv + 4 * i, kV);
      std::memcpy(&ri, r + 4 * i, kV);
      std::memcpy(&pi, p + 4 * i, kV);
      std::memcpy(&api, ap + 4 * i, kV);
      std::memcpy(&invi, inv + 4 * i, kV);
      dvi += pi * alpha;
      ri -= api * alpha;
      std::memcpy(dv + 4 * i, &dvi, kV);
      std::memcpy(r + 4 * i, &ri, kV);
      rz4 += __builtin_convertvector(ri * ri * invi, D4);
      r24 += __builtin_convertvector(ri * ri, D4);
      if (two_level) add_restricted(i, ri);
    }
    double rz_new = sum(rz4);
    r2 = sum(r24);
    ++it;
    if (it >= max_iterations || r2 <= d.stop2) break;  // no direction needed
    if (two_level) rz_new += coarse_solve(d);
    const T beta = static_cast<T>(rz_new / rz);
    rz = rz_new;
    for (std::size_t i = 0; i < nf; ++i) {
      V ri, pi, invi;
      std::memcpy(&ri, r + 4 * i, kV);
      std::memcpy(&pi, p + 4 * i, kV);
      std::memcpy(&invi, inv + 4 * i, kV);
      pi = ri * invi + pi * beta;
      if (two_level) {
        V xi;
        std::memcpy(&xi, d.xc + 4 * agg[i], kV);
        pi += xi;
      }
      std::memcpy(p + 4 * i, &pi, kV);
    }
  }
  return it;
}

BISTURI_HOT int cg_float(const CgData<float>& d, int max_iterations, double tol2, double& r2) {
  return cg_impl(d, max_iterations, tol2, r2);
}
BISTURI_HOT int cg_double(const CgData<double>& d, int max_iterations, double tol2, double& r2) {
  return cg_impl(d, max_iterations, tol2, r2);
}

}  // namespace

int run_cg(const CgData<float>& d, int max_iterations, double tol2, double& r2) {
  return cg_float(d, max_iterations, tol2, r2);
}
int run_cg(const CgData<double>& d, int max_iterations, double tol2, double& r2) {
  return cg_double(d, max_iterations, tol2, r2);
}

}  // namespace bisturi::sim
