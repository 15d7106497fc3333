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

/// out = A in; returns in . out. A = S + sum over the springs between free rows of their
/// blocks B = a I + s s^T (the clamped true spring Hessian and damping, spring_kernels.h),
/// applied as sum B (in_i - in_j): differences of neighbours instead of the diagonal minus a
/// sum of neighbours, so that float keeps its precision where the two nearly cancel (smooth
/// vectors). S is the rows' mass part; the blocks of springs to held vertices and contacts are
/// added after (product()).
template <class T>
BISTURI_INLINE void product_rows(const CgData<T>& d, const T* in, T* out, std::size_t first,
                                 std::size_t last, D4& acc_out) {
  using V = typename Lanes<T>::V;
  typedef float F4 __attribute__((vector_size(16)));
  D4 acc = {0.0, 0.0, 0.0, 0.0};  // in a register: the members' outputs share a cache line
  const std::uint32_t* row = d.row;
  const std::uint32_t* col = d.col;
  const float* blk = d.blk;
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
      F4 f0, f1;
      std::memcpy(&f0, blk + 4 * std::size_t(e), sizeof(F4));
      std::memcpy(&f1, blk + 4 * std::size_t(e + 1), sizeof(F4));
      V b0, b1;
      if constexpr (sizeof(T) == sizeof(float)) {
        b0 = f0;
        b1 = f1;
      } else {
        b0 = __builtin_convertvector(f0, V);
        b1 = __builtin_convertvector(f1, V);
      }
      const V d0 = pi - n0, d1 = pi - n1;
      const T s0 = d0[0] * b0[0] + d0[1] * b0[1] + d0[2] * b0[2];
      const T s1 = d1[0] * b1[0] + d1[1] * b1[1] + d1[2] * b1[2];
      s += (d0 * b0[3] + b0 * s0) + (d1 * b1[3] + b1 * s1);
    }
    s[3] = T(0);  // the blocks' a rode in lane 3
    std::memcpy(out + 4 * i, &s, sizeof(V));
    acc += __builtin_convertvector(pi * s, D4);
  }
  acc_out = acc;
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
  for (std::size_t c = 0; c < d.held; ++c) {
    const double* hb = d.held_blocks + 5 * c;
    const std::size_t ci = static_cast<std::size_t>(hb[0]);
    const T* pi = in + 4 * ci;
    const double sp = hb[1] * double(pi[0]) + hb[2] * double(pi[1]) + hb[3] * double(pi[2]);
    for (std::size_t l = 0; l < 3; ++l) {
      const double add = hb[4] * double(pi[l]) + sp * hb[1 + l];
      out[4 * ci + l] = static_cast<T>(double(out[4 * ci + l]) + add);
      in_out += add * double(pi[l]);
    }
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

/// The coarse correction: xc = (P^T A P)^-1 rc by the skyline Cholesky factor (forward, then
/// backward by columns so both sweeps read rows); returns rc . xc.
template <class T>
BISTURI_INLINE double coarse_solve(const CgData<T>& d) {
  using V = typename Lanes<T>::V;
  constexpr std::size_t kV = sizeof(V);
  const std::size_t nc = d.nc;
  T* x = d.xc;
  // factor_row(i)[j] is L_ij for j in [first[i], i].
  auto factor_row = [&](std::size_t i) { return d.chol + d.chol_start[i] - d.chol_first[i]; };
  for (std::size_t i = 0; i < nc; ++i) {
    const T* li = factor_row(i);
    V s;
    std::memcpy(&s, d.rc + 4 * i, kV);
    for (std::size_t j = d.chol_first[i]; j < i; ++j) {
      V xj;
      std::memcpy(&xj, x + 4 * j, kV);
      s -= xj * li[j];
    }
    s *= li[i];
    std::memcpy(x + 4 * i, &s, kV);
  }
  for (std::size_t i = nc; i-- > 0;) {
    const T* li = factor_row(i);
    V xi;
    std::memcpy(&xi, x + 4 * i, kV);
    xi *= li[i];
    std::memcpy(x + 4 * i, &xi, kV);
    for (std::size_t j = d.chol_first[i]; j < i; ++j) {
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

/// Calls rows(first, last, t) for every member's rows (all rows as member 0 without a team).
template <class T, class Rows>
BISTURI_INLINE void over_rows(const CgData<T>& d, const Rows& rows) {
  if (d.team == nullptr) {
    rows(std::size_t{0}, d.nf, 0u);
    return;
  }
  auto job = [&](unsigned t) { rows(std::size_t{d.part[t]}, std::size_t{d.part[t + 1]}, t); };
  d.team->run([&job](unsigned t) { job(t); });
}

/// The passes of one CG iteration over rows [first, last). Those that restrict the residual to
/// the coarse level add into rc (the member's own copy with a team) and return r . inv r and
/// r . r per lane.
template <class T>
struct CgRows {
  using V = typename Lanes<T>::V;
  static constexpr std::size_t kV = sizeof(V);
  const CgData<T>& d;
  bool two_level;

  /// z = B r with B row i's symmetric 3 x 3 block-Jacobi inverse (three 4-lane rows, pads 0).
  /// (Through a reference: a returned AVX vector changes the baseline clone's ABI.)
  BISTURI_INLINE void precondition(std::size_t i, const V& ri, V& z) const {
    V b0, b1, b2;
    std::memcpy(&b0, d.inv + 12 * i, kV);
    std::memcpy(&b1, d.inv + 12 * i + 4, kV);
    std::memcpy(&b2, d.inv + 12 * i + 8, kV);
    z = b0 * ri[0] + b1 * ri[1] + b2 * ri[2];
  }
  BISTURI_INLINE void restrict_to(T* rc, std::size_t i, const V& ri) const {
    V c;
    std::memcpy(&c, rc + 4 * d.agg[i], kV);
    c += ri;
    std::memcpy(rc + 4 * d.agg[i], &c, kV);
  }
  /// r = b - A dv, p = inv r.
  BISTURI_INLINE void first_residual(std::size_t first, std::size_t last, T* rc, D4& rz4_out,
                                     D4& r24_out) const {
    D4 rz4 = {}, r24 = {};  // in registers: the members' outputs share cache lines
    for (std::size_t i = first; i < last; ++i) {
      V bi, api;
      std::memcpy(&bi, d.b + 4 * i, kV);
      std::memcpy(&api, d.ap + 4 * i, kV);
      const V ri = bi - api;
      V zi;
      precondition(i, ri, zi);
      std::memcpy(d.r + 4 * i, &ri, kV);
      std::memcpy(d.p + 4 * i, &zi, kV);
      rz4 += __builtin_convertvector(ri * zi, D4);
      r24 += __builtin_convertvector(ri * ri, D4);
      if (two_level) restrict_to(rc, i, ri);
    }
    rz4_out = rz4;
    r24_out = r24;
  }
  /// p += P xc.
  BISTURI_INLINE void add_coarse(std::size_t first, std::size_t last) const {
    for (std::size_t i = first; i < last; ++i) {
      V pi, xi;
      std::memcpy(&pi, d.p + 4 * i, kV);
      std::memcpy(&xi, d.xc + 4 * d.agg[i], kV);
      pi += xi;
      std::memcpy(d.p + 4 * i, &pi, kV);
    }
  }
  /// dv += alpha p, r -= alpha A p.
  BISTURI_INLINE void update(std::size_t first, std::size_t last, T alpha, T* rc, D4& rz4_out,
                             D4& r24_out) const {
    D4 rz4 = {}, r24 = {};
    for (std::size_t i = first; i < last; ++i) {
      V dvi, ri, pi, api;
      std::memcpy(&dvi, d.dv + 4 * i, kV);
      std::memcpy(&ri, d.r + 4 * i, kV);
      std::memcpy(&pi, d.p + 4 * i, kV);
      std::memcpy(&api, d.ap + 4 * i, kV);
      dvi += pi * alpha;
      ri -= api * alpha;
      std::memcpy(d.dv + 4 * i, &dvi, kV);
      std::memcpy(d.r + 4 * i, &ri, kV);
      V zi;
      precondition(i, ri, zi);
      rz4 += __builtin_convertvector(ri * zi, D4);
      r24 += __builtin_convertvector(ri * ri, D4);
      if (two_level) restrict_to(rc, i, ri);
    }
    rz4_out = rz4;
    r24_out = r24;
  }
  /// p = inv r + P xc + beta p.
  BISTURI_INLINE void direction(std::size_t first, std::size_t last, T beta) const {
    for (std::size_t i = first; i < last; ++i) {
      V ri, pi;
      std::memcpy(&ri, d.r + 4 * i, kV);
      std::memcpy(&pi, d.p + 4 * i, kV);
      V zi;
      precondition(i, ri, zi);
      pi = zi + pi * beta;
      if (two_level) {
        V xi;
        std::memcpy(&xi, d.xc + 4 * d.agg[i], kV);
        pi += xi;
      }
      std::memcpy(d.p + 4 * i, &pi, kV);
    }
  }
};

/// Runs a restricting pass (first_residual or update) over the members' rows: each member
/// restricts into its own coarse vector (member 0 into d.rc) and keeps its own sums; the
/// members' coarse vectors and sums are added in member order.
template <class T, class Pass>
BISTURI_INLINE void restricting_pass(const CgData<T>& d, bool two_level, const Pass& pass,
                                     double& rz, double& r2) {
  const unsigned members = d.team == nullptr ? 1u : d.team->size();
  const std::size_t n4c = 4 * d.nc;
  std::array<D4, kMaxThreads> rz4, r24;
  over_rows(d, [&](std::size_t first, std::size_t last, unsigned t) {
    T* rc = t == 0 ? d.rc : d.rc_parts + (t - 1) * n4c;
    if (two_level) std::fill(rc, rc + n4c, T(0));
    pass(first, last, rc, rz4[t], r24[t]);
  });
  for (unsigned t = 1; t < members; ++t) {
    rz4[0] += rz4[t];
    r24[0] += r24[t];
    if (!two_level) continue;
    const T* part = d.rc_parts + (t - 1) * n4c;
    for (std::size_t e = 0; e < n4c; ++e)
      d.rc[e] += part[e];
  }
  rz = (rz4[0][0] + rz4[0][1]) + (rz4[0][2] + rz4[0][3]);
  r2 = (r24[0][0] + r24[0][1]) + (r24[0][2] + r24[0][3]);
}

/// Block-Jacobi-preconditioned CG from the start value in d.dv; returns the iterations, r2 the last
/// squared residual. Three passes per iteration: A p (with p . A p), the update of dv and r (with
/// r . z and r . r), the new direction. z = inv r + P xc is never stored: r . z is r . inv r plus
/// rc . xc, and the direction pass adds P xc itself.
template <class T>
BISTURI_INLINE int cg_impl(const CgData<T>& d, int max_iterations, double tol2, double& r2) {
  const bool two_level = d.nc > 0;
  const CgRows<T> rows{d, two_level};
  double rz = 0.0;
  product(d, d.dv, d.ap);
  restricting_pass(
      d, two_level,
      [&](std::size_t first, std::size_t last, T* rc, D4& rz4, D4& r24) {
        rows.first_residual(first, last, rc, rz4, r24);
      },
      rz, r2);
  if (two_level) {
    rz += coarse_solve(d);
    over_rows(d,
              [&](std::size_t first, std::size_t last, unsigned) { rows.add_coarse(first, last); });
  }
  int it = 0;
  while (it < max_iterations && r2 > tol2) {  // tol2 starts the solve, d.stop2 ends it
    const double pap = product(d, d.p, d.ap);
    if (!(pap > 0.0)) break;
    const T alpha = static_cast<T>(rz / pap);
    double rz_new = 0.0;
    restricting_pass(
        d, two_level,
        [&](std::size_t first, std::size_t last, T* rc, D4& rz4, D4& r24) {
          rows.update(first, last, alpha, rc, rz4, r24);
        },
        rz_new, r2);
    ++it;
    if (it >= max_iterations || r2 <= d.stop2) break;  // no direction needed
    if (two_level) rz_new += coarse_solve(d);
    const T beta = static_cast<T>(rz_new / rz);
    rz = rz_new;
    over_rows(d, [&](std::size_t first, std::size_t last, unsigned) {
      rows.direction(first, last, beta);
    });
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
