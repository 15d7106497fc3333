#include "bisturi/sim/integrator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <type_traits>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"
#include "step_threads.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kIndexMask = (1u << 30) - 1u;
constexpr std::uint32_t kNotFree = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kMaxStructures = 16;
constexpr double kNeverQuiet = std::numeric_limits<double>::infinity();
constexpr unsigned kMaxThreads = 64;
/// Springs per block of the spring passes: gathered into small arrays, computed in a loop the
/// compiler vectorises (sqrt and division four or two at a time), then scattered.
constexpr std::size_t kChunk = 64;

// The hot loops are compiled twice, for AVX2 and for the generic x86-64 baseline, and picked at
// load time (no -march: the binary runs on any x86-64). Neither clone uses FMA and every
// reduction keeps the same per-lane order, so both give the same bits.
#if defined(__GNUC__) && defined(__x86_64__) && !defined(__clang__)
#define BISTURI_HOT [[gnu::target_clones("avx2", "default")]]
#else
#define BISTURI_HOT
#endif
#define BISTURI_INLINE [[gnu::always_inline]] inline

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

/// The CG's data, four lanes (x, y, z, zero pad) per free vertex.
template <class T>
struct CgData {
  std::size_t nf = 0;
  const std::uint32_t* row = nullptr;  ///< nf + 1 offsets into col
  const std::uint32_t* col = nullptr;  ///< neighbour | class << 30, even count per row
  const T* self = nullptr;             ///< per row: the diagonal less the free neighbours' weights
  const T* inv = nullptr;              ///< Jacobi: inverse of the diagonal, contact blocks included
  const T* b = nullptr;                ///< right-hand side
  T w[4] = {};                         ///< class weights
  const double* contact = nullptr;     ///< 5 per contact: compact index, nx, ny, nz, k
  std::size_t contacts = 0;
  T *dv = nullptr, *r = nullptr, *p = nullptr, *ap = nullptr;
  // Coarse level (nc = 0: Jacobi alone): row -> aggregate, packed Cholesky factor (inverted
  // diagonal), and two 4-lane vectors of nc aggregates.
  std::size_t nc = 0;
  const std::uint32_t* agg = nullptr;
  const T* chol = nullptr;
  T *rc = nullptr, *xc = nullptr;
  double stop2 = 0.0;  ///< squared residual that ends a solve once it has started
  // Threads (team != nullptr): member t multiplies rows [part[t], part[t + 1]).
  StepThreads* team = nullptr;
  const std::uint32_t* part = nullptr;
};

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

int run_cg(const CgData<float>& d, int max_iterations, double tol2, double& r2) {
  return cg_float(d, max_iterations, tol2, r2);
}
int run_cg(const CgData<double>& d, int max_iterations, double tol2, double& r2) {
  return cg_double(d, max_iterations, tol2, r2);
}

}  // namespace

ImplicitIntegrator::Structure& ImplicitIntegrator::structure(const SoftBody& body) {
  const std::uint64_t generation = body.derived_generation();
  for (Structure& s : structures_) {
    if (s.generation == generation) return s;
  }
  if (structures_.size() >= kMaxStructures) structures_.erase(structures_.begin());
  Structure st;
  st.generation = generation;
  const auto& springs = body.springs();
  const std::size_t n = body.positions().size();
  if (n > kIndexMask) throw SimInputError("integrator: more than 2^30 vertex slots");
  const std::size_t ns = springs.size();
  st.a.resize(ns);
  st.b.resize(ns);
  st.rest.resize(ns);
  st.k.resize(ns);
  st.spring_class.resize(ns);
  std::size_t classes = 0;
  for (std::size_t s = 0; s < ns; ++s) {
    const Spring& sp = springs[s];
    st.a[s] = sp.a;
    st.b[s] = sp.b;
    st.rest[s] = sp.rest_m;
    st.k[s] = sp.k_N_per_m;
    // Springs come in a few stiffness classes (one per kind): the rows store the class.
    std::size_t c = 0;
    while (c < classes && st.k_class[c] != sp.k_N_per_m)
      ++c;
    if (c == classes) {
      if (classes == 4) throw SimInputError("integrator: more than four spring stiffnesses");
      st.k_class[classes++] = sp.k_N_per_m;
    }
    st.spring_class[s] = static_cast<std::uint8_t>(c);
  }
  structures_.push_back(std::move(st));
  return structures_.back();
}

void ImplicitIntegrator::update_free_rows(Structure& st, const std::vector<std::uint8_t>& mask,
                                          const std::vector<double>& masses) {
  if (st.free_mask == mask && !st.full.row.empty()) return;
  st.free_mask = mask;
  build_system(st, st.full, mask);
  aggregate(st.full);
  // The aggregates' rows, for sleeping whole aggregates.
  const std::size_t nf = st.full.vertex.size();
  const std::size_t nc = st.full.coarse_count;
  st.agg_start.assign(nc + 1, 0);
  for (std::size_t i = 0; i < nf; ++i)
    ++st.agg_start[st.full.agg[i] + 1];
  for (std::size_t c = 0; c < nc; ++c)
    st.agg_start[c + 1] += st.agg_start[c];
  st.agg_rows.resize(nf);
  std::vector<std::uint32_t> fill(st.agg_start.begin(), st.agg_start.end() - 1);
  for (std::size_t i = 0; i < nf; ++i)
    st.agg_rows[fill[st.full.agg[i]]++] = static_cast<std::uint32_t>(i);
  st.agg_mass2.assign(nc, 0.0);
  for (std::size_t i = 0; i < nf; ++i) {
    const double mi = masses[st.full.vertex[i]];
    st.agg_mass2[st.full.agg[i]] += mi * mi;
  }
  for (auto* v : {&st.sleep_p6, &st.sleep_residual, &st.sleep_gradient, &st.step_residual,
                  &st.step_speed, &st.step_gradient})
    v->assign(nc, 0.0);
  st.awake.assign(nc, 1);
  st.quiet.assign(nc, 0);
  st.asleep = 0;
  st.part_dirty = true;
}

void ImplicitIntegrator::build_system(const Structure& st, System& sys,
                                      const std::vector<std::uint8_t>& mask) {
  sys.agg.clear();
  sys.coarse_h = -1.0;
  sys.fixed_energy_valid = false;
  const std::size_t n = mask.size();
  sys.vertex.clear();
  sys.compact.assign(n, kNotFree);
  for (std::size_t i = 0; i < n; ++i) {
    if (mask[i]) {
      sys.compact[i] = static_cast<std::uint32_t>(sys.vertex.size());
      sys.vertex.push_back(static_cast<std::uint32_t>(i));
    }
  }
  const std::size_t nf = sys.vertex.size();
  // Four segments per row, one per stiffness class (segment 4 r + class), each in spring order:
  // the product sums a segment's neighbour differences and scales the sum once by the class's
  // weight. Springs to constrained vertices only count towards the row's diagonal.
  sys.row.assign(4 * nf + 1, 0);
  sys.fixed_count.assign(4 * nf, 0);
  const std::size_t ns = st.a.size();
  std::size_t active = 0;
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ca = sys.compact[st.a[s]], cb = sys.compact[st.b[s]];
    const std::uint32_t cls = st.spring_class[s];
    if (ca != kNotFree && cb != kNotFree) {
      ++sys.row[4 * ca + cls + 1];
      ++sys.row[4 * cb + cls + 1];
    } else if (ca != kNotFree) {
      ++sys.fixed_count[4 * ca + cls];
    } else if (cb != kNotFree) {
      ++sys.fixed_count[4 * cb + cls];
    }
    if (ca != kNotFree || cb != kNotFree) ++active;
  }
  for (std::size_t i = 0; i < 4 * nf; ++i)
    sys.row[i + 1] += sys.row[i];
  sys.col.resize(sys.row[4 * nf]);
  std::vector<std::uint32_t> fill(sys.row.begin(), sys.row.end() - 1);
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ca = sys.compact[st.a[s]], cb = sys.compact[st.b[s]];
    if (ca == kNotFree || cb == kNotFree) continue;
    sys.col[fill[4 * ca + st.spring_class[s]]++] = cb;
    sys.col[fill[4 * cb + st.spring_class[s]]++] = ca;
  }
  // The product's form: one run per row, each entry a neighbour with its class in the top two
  // bits, padded to an even length with the row itself (in_i - in_i adds an exact zero), so the
  // product takes two neighbours per trip with one loop exit per row.
  sys.prow.assign(nf + 1, 0);
  sys.pcol.clear();
  sys.pcol.reserve(sys.col.size() + nf);
  for (std::size_t i = 0; i < nf; ++i) {
    for (std::uint32_t k = 0; k < 4; ++k) {
      for (std::uint32_t e = sys.row[4 * i + k]; e < sys.row[4 * i + k + 1]; ++e)
        sys.pcol.push_back(sys.col[e] | (k << 30));
    }
    if ((sys.pcol.size() - sys.prow[i]) % 2 != 0) sys.pcol.push_back(static_cast<std::uint32_t>(i));
    sys.prow[i + 1] = static_cast<std::uint32_t>(sys.pcol.size());
  }
  // The two spring sets, in spring order, padded with null springs (vertex 0 to itself).
  auto reset = [](System::SpringSet& set, std::size_t count) {
    const std::size_t padded = (count + 3) / 4 * 4;
    set.count = count;
    set.a.assign(padded, 0);
    set.b.assign(padded, 0);
    set.rest.assign(padded, 0.0);
    set.k.assign(padded, 0.0);
  };
  reset(sys.active, active);
  reset(sys.fixed, ns - active);
  std::size_t ia = 0, ix = 0;
  for (std::size_t s = 0; s < ns; ++s) {
    const bool is_active = sys.compact[st.a[s]] != kNotFree || sys.compact[st.b[s]] != kNotFree;
    System::SpringSet& set = is_active ? sys.active : sys.fixed;
    std::size_t& i = is_active ? ia : ix;
    set.a[i] = st.a[s];
    set.b[i] = st.b[s];
    set.rest[i] = st.rest[s];
    set.k[i] = st.k[s];
    ++i;
  }
}

void ImplicitIntegrator::aggregate(System& sys) {
  const std::size_t nf = sys.vertex.size();
  const std::uint32_t* row = sys.row.data();
  const std::uint32_t* col = sys.col.data();
  // Aggregates: a seed whose neighbours are all unassigned takes them and grows by whole rings
  // of neighbours until it holds `target` rows; leftovers join an assigned neighbour's
  // aggregate. About nf / 192 aggregates (the dense coarse solve stays below a fifth of a
  // product at 20k vertices), but no more than 80 rows each: at 95k vertices aggregates of
  // 330 rows left a relative residual of 0.65 after 6 iterations, of 80 rows 0.02.
  const std::size_t target = std::clamp<std::size_t>(nf / 192, 8, 80);
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  sys.agg.assign(nf, kNone);
  std::uint32_t count = 0;
  std::vector<std::uint32_t> ring, next;
  for (std::size_t seed = 0; seed < nf; ++seed) {
    if (sys.agg[seed] != kNone) continue;
    bool free_around = true;
    for (std::uint32_t e = row[4 * seed]; e < row[4 * seed + 4] && free_around; ++e)
      free_around = sys.agg[col[e]] == kNone;
    if (!free_around) continue;
    sys.agg[seed] = count;
    std::size_t size = 1;
    ring.assign(1, static_cast<std::uint32_t>(seed));
    while (size < target && !ring.empty()) {
      next.clear();
      for (std::uint32_t i : ring) {
        for (std::uint32_t e = row[4 * i]; e < row[4 * i + 4]; ++e) {
          if (sys.agg[col[e]] != kNone) continue;
          sys.agg[col[e]] = count;
          next.push_back(col[e]);
          ++size;
        }
      }
      ring.swap(next);
    }
    ++count;
  }
  for (bool changed = true; changed;) {
    changed = false;
    for (std::size_t i = 0; i < nf; ++i) {
      if (sys.agg[i] != kNone) continue;
      for (std::uint32_t e = row[4 * i]; e < row[4 * i + 4]; ++e) {
        if (sys.agg[col[e]] != kNone) {
          sys.agg[i] = sys.agg[col[e]];
          changed = true;
          break;
        }
      }
    }
  }
  for (std::size_t i = 0; i < nf; ++i) {  // rows with no free neighbour at all
    if (sys.agg[i] == kNone) sys.agg[i] = count++;
  }
  sys.coarse_count = count;
}

void ImplicitIntegrator::update_coarse(System& sys, const Structure& st, const SoftBody& body,
                                       double h) {
  if (sys.coarse_h == h) return;
  const std::size_t nf = sys.vertex.size();
  const std::uint32_t* row = sys.row.data();
  const std::uint32_t* col = sys.col.data();
  // P^T A P with P the aggregates' indicator: each aggregate sums its rows' diagonal parts that
  // are not a free neighbour's weight, and the weights of springs leaving it.
  const std::size_t nc = sys.coarse_count;
  const auto& m = body.masses();
  const Material& mat = body.material();
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h * h * st.k_class[k] + h * mat.spring_damping_N_s_per_m;
  std::vector<double> a(nc * nc, 0.0);
  for (std::size_t i = 0; i < nf; ++i) {
    const std::size_t I = sys.agg[i];
    double self = m[sys.vertex[i]] * (1.0 + h * mat.drag_per_s);
    for (std::size_t k = 0; k < 4; ++k) {
      self += double(sys.fixed_count[4 * i + k]) * w[k];
      for (std::uint32_t e = row[4 * i + k]; e < row[4 * i + k + 1]; ++e) {
        const std::size_t J = sys.agg[col[e]];
        if (J == I) continue;
        a[I * nc + I] += w[k];
        a[I * nc + J] -= w[k];
      }
    }
    a[I * nc + I] += self;
  }
  // Dense Cholesky, packed lower rows (row I holds columns 0..I), 1 / L_II on the diagonal.
  sys.coarse.assign(nc * (nc + 1) / 2, 0.0);
  double* L = sys.coarse.data();
  auto at = [](std::size_t i, std::size_t j) { return i * (i + 1) / 2 + j; };
  for (std::size_t i = 0; i < nc; ++i) {
    for (std::size_t j = 0; j <= i; ++j) {
      double sum = a[i * nc + j];
      const double* li = L + at(i, 0);
      const double* lj = L + at(j, 0);
      for (std::size_t k = 0; k < j; ++k)
        sum -= li[k] * lj[k];
      if (j < i) {
        L[at(i, j)] = sum * L[at(j, j)];
      } else {
        L[at(i, i)] = sum > 0.0 ? 1.0 / std::sqrt(sum) : 0.0;  // SPD; 0 drops a bad aggregate
      }
    }
  }
  sys.coarse_f.resize(sys.coarse.size());
  for (std::size_t i = 0; i < sys.coarse.size(); ++i)
    sys.coarse_f[i] = static_cast<float>(sys.coarse[i]);
  sys.coarse_h = h;
}

void ImplicitIntegrator::free_mask(const SoftBody& body) {
  const auto& m = body.masses();
  const std::size_t n = m.size();
  free_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    free_[i] = (m[i] <= 0.0 || body.anchored(vi) || body.kinematic(vi)) ? 0 : 1;
  }
}

void ImplicitIntegrator::prepare(SoftBody& body, const IntegratorOptions& options) {
  body.refresh_topology();
  Structure& st = structure(body);
  free_mask(body);
  update_free_rows(st, free_, body.masses());
  if (options.cg_coarse_level) update_coarse(st.full, st, body, options.dt_s);
  // Scratch at its working size, so the first step allocates nothing.
  const std::size_t n = body.positions().size();
  const std::size_t n4 = 4 * st.full.vertex.size();
  saved_x_.reserve(n);
  saved_v_.reserve(n);
  f_.reserve(n);
  grad_.reserve(n);
  for (auto* vec : {&rhs_, &inv_diag_, &dv_})
    vec->reserve(n4);
  diag_.reserve(n4 / 4);
  self_.reserve(n4 / 4);
  fbuf_.reserve(5 * n4 + n4 / 4);
  dbuf_.reserve(3 * n4);
}

StepStats ImplicitIntegrator::step(SoftBody& body, const IntegratorOptions& options,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step_index) {
  StepStats stats;
  step_team_ = team(options);
  body.refresh_topology();
  if (body.frozen()) {
    body.clear_forces();
    stats.frozen = true;
    return stats;
  }
  Structure& st = structure(body);
  if (options.sleeping && sleeps_entirely(st, body)) {
    stats.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
    body.clear_forces();
    return stats;
  }
  auto& x = body.positions();
  auto& v = body.velocities();
  saved_x_ = x;
  saved_v_ = v;
  const auto& masses = body.masses();
  bool any_kinematic = false;
  for (std::size_t i = 0; i < masses.size(); ++i) {
    if (body.kinematic(VertexId(static_cast<std::uint32_t>(i)))) any_kinematic = true;
  }
  const bool energy_check = !any_kinematic;
  double energy_before = 0.0;
  // Kinematic vertices move their neighbours every step: nothing sleeps while there are any.
  if (!options.sleeping || any_kinematic) wake_all(st);

  for (int attempt = 0; attempt <= options.max_retry_halvings; ++attempt) {
    const int substeps = 1 << attempt;
    const double h = options.dt_s / substeps;
    StepStats trial;
    trial.substeps = substeps;
    System* sys = nullptr;
    for (int s = 0; s < substeps; ++s) {
      // The energy of the start state comes out of the first substep's force pass for free.
      const bool first = attempt == 0 && s == 0 && energy_check;
      sys = &substep(body, st, options, h, double(s + 1) / substeps, trial,
                     first ? &energy_before : nullptr);
    }
    const std::string reason = check(body, *sys, options, energy_before, energy_check);
    if (reason.empty()) {
      trial.rolled_back = attempt > 0;
      trial.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
      trial.awake_vertices = static_cast<std::uint32_t>(sys->vertex.size());
      if (options.sleeping && !any_kinematic && attempt == 0) update_sleep(st, body, options);
      body.clear_forces();
      return trial;
    }
    events.push_back({SimEventKind::RolledBack, body_index, step_index, substeps, reason});
    x = saved_x_;
    v = saved_v_;
    std::fill(body.warm_start().begin(), body.warm_start().end(), glm::dvec3(0.0));
  }
  events.push_back({SimEventKind::Frozen, body_index, step_index, 1 << options.max_retry_halvings,
                    "still diverging with the smallest substep: the solid is frozen"});
  body.freeze();
  stats.frozen = true;
  stats.rolled_back = true;
  return stats;
}

std::string ImplicitIntegrator::check(const SoftBody& body, System& st,
                                      const IntegratorOptions& options, double energy_before,
                                      bool energy_check) const {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const glm::dvec3 g = options.gravity_m_s2;
  const double max_speed2 = options.max_speed_m_s * options.max_speed_m_s;
  // One sweep: the external forces' work over the step, finiteness, the fastest vertex and the
  // kinetic and gravitational energies.
  double work = 0.0, sum = 0.0, fastest = 0.0, kinetic = 0.0, potential = 0.0;
  const std::size_t n = x.size();
  for (std::size_t i = 0; i < n; ++i) {
    const glm::dvec3 xi = x[i], vi = v[i];
    work += glm::dot(fext[i], xi - saved_x_[i]);
    sum += xi.x + xi.y + xi.z + vi.x + vi.y + vi.z;
    const double v2 = glm::dot(vi, vi);
    fastest = std::max(fastest, v2);
    kinetic += 0.5 * m[i] * v2;
    potential -= m[i] * glm::dot(g, xi);
  }
  if (!std::isfinite(work)) return "non-finite external force";
  if (!std::isfinite(sum) || !std::isfinite(fastest)) {
    for (std::size_t i = 0; i < n; ++i) {
      const double s = x[i].x + x[i].y + x[i].z + v[i].x + v[i].y + v[i].z;
      if (!std::isfinite(s)) return "non-finite state at vertex " + std::to_string(i);
    }
    return "non-finite state";
  }
  if (fastest > max_speed2) {
    for (std::size_t i = 0; i < n; ++i) {
      if (glm::dot(v[i], v[i]) > max_speed2) {
        return "vertex " + std::to_string(i) + " faster than " +
               std::to_string(options.max_speed_m_s) + " m/s";
      }
    }
  }
  if (!energy_check) return {};
  // Springs between constrained vertices did not move: their energy is the start state's.
  const System::SpringSet& sa = st.active;
  double elastic = fixed_energy(st, body);
  if (step_team_ == nullptr) {
    elastic +=
        spring_energy(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(), sa.a.size(), x.data());
  } else {
    const unsigned members = step_team_->size();
    std::array<double, kMaxThreads> partial{};
    struct Energy {
      const System::SpringSet& sa;
      const glm::dvec3* x;
      unsigned members;
      std::array<double, kMaxThreads>& partial;
      void operator()(unsigned t) const {
        const Range r = part_of(sa.a.size(), members, t, kChunk);
        partial[t] =
            spring_energy(sa.a.data() + r.begin, sa.b.data() + r.begin, sa.rest.data() + r.begin,
                          sa.k.data() + r.begin, r.end - r.begin, x);
      }
    } job{sa, x.data(), members, partial};
    step_team_->run([&job](unsigned t) { job(t); });
    for (unsigned t = 0; t < members; ++t)
      elastic += partial[t];
  }
  if (body.closed() && body.rest_volume_m3() > 0.0) {
    const double dv = body.volume_m3() - body.rest_volume_m3();
    elastic += 0.5 * body.material().bulk_modulus_Pa * dv * dv / body.rest_volume_m3();
  }
  const double energy_after = kinetic + potential + elastic;
  if (!std::isfinite(energy_after)) return "non-finite energy";
  const double allowed = std::max(0.0, work) + options.energy_jump_J +
                         options.energy_jump_relative * std::abs(energy_before);
  if (energy_after - energy_before > allowed) {
    return "energy rose by " + std::to_string(energy_after - energy_before) + " J (allowed " +
           std::to_string(allowed) + " J)";
  }
  return {};
}

template <class T>
void ImplicitIntegrator::solve(const System& st, const double (&w)[4], int max_iterations,
                               double rel_tol2, double abs_tol2, StepStats& stats) {
  const std::size_t nf = st.vertex.size();
  const std::size_t n4 = 4 * nf;
  CgData<T> d;
  d.nf = nf;
  d.row = st.prow.data();
  d.col = st.pcol.data();
  for (int k = 0; k < 4; ++k)
    d.w[k] = static_cast<T>(w[k]);
  d.contact = contacts_.data();
  d.contacts = contacts_.size() / 5;
  if (step_team_ != nullptr) {
    // Rows split by their entries, so each member gathers about as much.
    const unsigned n = step_team_->size();
    row_parts_.resize(n + 1);
    const std::uint32_t entries = nf > 0 ? st.prow[nf] : 0;
    for (unsigned t = 0; t <= n; ++t) {
      const std::uint64_t goal = std::uint64_t{entries} * t / n;
      row_parts_[t] = static_cast<std::uint32_t>(
          std::lower_bound(st.prow.begin(), st.prow.begin() + static_cast<std::ptrdiff_t>(nf),
                           goal) -
          st.prow.begin());
    }
    row_parts_[n] = static_cast<std::uint32_t>(nf);
    d.team = step_team_;
    d.part = row_parts_.data();
  }
  double b2 = 0.0;
  {
    double b24[4] = {0.0, 0.0, 0.0, 0.0};
    for (std::size_t i = 0; i < n4; i += 4) {
      for (std::size_t l = 0; l < 4; ++l)
        b24[l] += rhs_[i + l] * rhs_[i + l];
    }
    b2 = (b24[0] + b24[1]) + (b24[2] + b24[3]);
  }
  // A solve starts when the residual is above either tolerance; once started, it goes on to a
  // tenth of the absolute one (or to the relative one): a body settling then leaves a residual
  // well under the threshold and its next steps cost no iteration, where stopping just under it
  // left every later step just above it (one or two iterations per step at rest).
  const double tol2 = std::max(rel_tol2 * b2, abs_tol2);
  d.stop2 = std::max(rel_tol2 * b2, 0.01 * abs_tol2);
  // When dv = 0 already meets the absolute tolerance, it is the answer: the warm start (the last
  // step's dv) would meet it too, but applying it again step after step keeps a resting body
  // moving at the tolerance's level.
  if (b2 <= abs_tol2) std::fill(dv_.begin(), dv_.end(), 0.0);
  if constexpr (std::is_same_v<T, double>) {
    dbuf_.resize(3 * n4);
    d.self = self_.data();
    d.inv = inv_diag_.data();
    d.b = rhs_.data();
    d.dv = dv_.data();
    d.r = dbuf_.data();
    d.p = d.r + n4;
    d.ap = d.p + n4;
  } else {
    // Layout: r, p, ap, dv, b, inv (4 lanes each), self (1 per row).
    fbuf_.resize(6 * n4 + nf);
    float* f = fbuf_.data();
    d.r = f;
    d.p = f + n4;
    d.ap = f + 2 * n4;
    d.dv = f + 3 * n4;
    float* b = f + 4 * n4;
    float* inv = f + 5 * n4;
    float* self = f + 6 * n4;
    for (std::size_t e = 0; e < n4; ++e) {
      d.dv[e] = static_cast<float>(dv_[e]);
      b[e] = static_cast<float>(rhs_[e]);
      inv[e] = static_cast<float>(inv_diag_[e]);
    }
    for (std::size_t i = 0; i < nf; ++i)
      self[i] = static_cast<float>(self_[i]);
    d.b = b;
    d.inv = inv;
    d.self = self;
  }
  if (!st.agg.empty() && st.coarse_h > 0.0) {
    d.nc = st.coarse_count;
    d.agg = st.agg.data();
    if constexpr (std::is_same_v<T, double>) {
      d.chol = st.coarse.data();
    } else {
      d.chol = st.coarse_f.data();
    }
    T* cbuf = nullptr;
    if constexpr (std::is_same_v<T, double>) {
      cbuf_d_.assign(8 * d.nc, 0.0);
      cbuf = cbuf_d_.data();
    } else {
      cbuf_f_.assign(8 * d.nc, 0.0f);
      cbuf = cbuf_f_.data();
    }
    d.rc = cbuf;
    d.xc = d.rc + 4 * d.nc;
  }
  double r2 = 0.0;
  const int it = run_cg(d, max_iterations, tol2, r2);
  if constexpr (!std::is_same_v<T, double>) {
    for (std::size_t e = 0; e < n4; ++e)
      dv_[e] = double(d.dv[e]);
  }
  stats.cg_iterations += it;
  stats.relative_residual = std::sqrt(r2 / std::max(b2, 1e-300));
}

double ImplicitIntegrator::fixed_energy(System& sys, const SoftBody& body) {
  if (!sys.fixed_energy_valid) {
    const System::SpringSet& sx = sys.fixed;
    sys.fixed_energy = spring_energy(sx.a.data(), sx.b.data(), sx.rest.data(), sx.k.data(),
                                     sx.a.size(), body.positions().data());
    sys.fixed_energy_valid = true;
  }
  return sys.fixed_energy;
}

double ImplicitIntegrator::spring_pass(System& sys, const SoftBody& body, double h, bool energy) {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const double c = body.material().spring_damping_N_s_per_m;
  f_.assign(x.size(), glm::dvec3(0.0));
  const System::SpringSet& sa = sys.active;
  double elastic = 0.0;
  if (step_team_ != nullptr) {
    elastic = spring_pass_parts(sa, x, v, c, h, energy);
    if (energy) elastic += fixed_energy(sys, body);
  } else if (energy) {
    elastic = spring_forces_energy(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(),
                                   sa.a.size(), sa.count, x.data(), v.data(), c, h, f_.data()) +
              fixed_energy(sys, body);
  } else {
    spring_forces(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(), sa.a.size(), sa.count,
                  x.data(), v.data(), c, h, f_.data());
  }
  // The halo completes the spring forces on the border of the awake region (for waking).
  const System::SpringSet& sb = sys.halo;
  if (sb.count > 0) {
    spring_forces(sb.a.data(), sb.b.data(), sb.rest.data(), sb.k.data(), sb.a.size(), sb.count,
                  x.data(), v.data(), c, h, f_.data());
  }
  return elastic;
}

double ImplicitIntegrator::spring_pass_parts(const System::SpringSet& sa,
                                             const std::vector<glm::dvec3>& x,
                                             const std::vector<glm::dvec3>& v, double c, double h,
                                             bool energy) {
  // Member t takes a run of the springs into its own force array (member 0 into f_), then the
  // arrays are added in member order, each member a run of vertices.
  const unsigned n = step_team_->size();
  f_parts_.resize(n - 1);
  std::array<double, kMaxThreads> partial{};
  struct Springs {
    ImplicitIntegrator& self;
    const System::SpringSet& sa;
    const glm::dvec3* x;
    const glm::dvec3* v;
    double c, h;
    bool energy;
    unsigned n;
    std::array<double, kMaxThreads>& partial;
    void operator()(unsigned t) const {
      glm::dvec3* f = self.f_.data();
      if (t > 0) {
        self.f_parts_[t - 1].assign(self.f_.size(), glm::dvec3(0.0));
        f = self.f_parts_[t - 1].data();
      }
      const Range r = part_of(sa.a.size(), n, t, kChunk);
      const std::size_t real = sa.count > r.begin ? std::min(sa.count, r.end) - r.begin : 0;
      const std::size_t b = r.begin, m = r.end - r.begin;
      if (energy) {
        partial[t] = spring_forces_energy(sa.a.data() + b, sa.b.data() + b, sa.rest.data() + b,
                                          sa.k.data() + b, m, real, x, v, c, h, f);
      } else {
        spring_forces(sa.a.data() + b, sa.b.data() + b, sa.rest.data() + b, sa.k.data() + b, m,
                      real, x, v, c, h, f);
      }
    }
  } springs{*this, sa, x.data(), v.data(), c, h, energy, n, partial};
  step_team_->run([&springs](unsigned t) { springs(t); });
  struct Sum {
    ImplicitIntegrator& self;
    unsigned n;
    void operator()(unsigned t) const {
      const Range r = part_of(self.f_.size(), n, t);
      for (std::size_t i = r.begin; i < r.end; ++i) {
        glm::dvec3 s = self.f_[i];
        for (unsigned p = 0; p + 1 < n; ++p)
          s += self.f_parts_[p][i];
        self.f_[i] = s;
      }
    }
  } sum{*this, n};
  step_team_->run([&sum](unsigned t) { sum(t); });
  double elastic = 0.0;
  for (unsigned t = 0; t < n; ++t)
    elastic += partial[t];
  return elastic;
}

StepThreads* ImplicitIntegrator::team(const IntegratorOptions& options) {
  const unsigned want = std::min(options.threads, kMaxThreads);
  if (want <= 1) return nullptr;
  if (!team_ || team_->size() != want) team_ = std::make_shared<StepThreads>(want);
  return team_.get();
}

ImplicitIntegrator::System& ImplicitIntegrator::substep(SoftBody& body, Structure& st,
                                                        const IntegratorOptions& options, double h,
                                                        double fraction, StepStats& stats,
                                                        double* energy_out) {
  auto& x = body.positions();
  auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const Material& mat = body.material();
  const std::size_t n = x.size();
  const double drag = mat.drag_per_s;
  const double c = mat.spring_damping_N_s_per_m;
  const glm::dvec3 g = options.gravity_m_s2;
  const double h2 = h * h;

  // Constraints: anchored and massless vertices stand still, kinematic ones follow their target.
  // Vertices with an external load are noted: they may not sleep.
  free_.resize(n);
  loaded_.clear();
  double kinetic = 0.0, potential = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    std::uint8_t is_free = 1;
    if (m[i] <= 0.0 || body.anchored(vi)) {
      is_free = 0;
      v[i] = glm::dvec3(0.0);
    } else if (body.kinematic(vi)) {
      is_free = 0;
      // The target is reached at the end of the step; substeps follow the straight line.
      const glm::dvec3 goal = saved_x_[i] + (body.kinematic_target(vi) - saved_x_[i]) * fraction;
      v[i] = (goal - x[i]) / h;
    }
    free_[i] = is_free;
    if (fext[i] != glm::dvec3(0.0)) loaded_.push_back(static_cast<std::uint32_t>(i));
    if (energy_out) {
      kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
      potential -= m[i] * glm::dot(g, x[i]);
    }
  }
  update_free_rows(st, free_, m);
  if (st.asleep > 0) wake_loaded(st, body);
  System* sys = &system(st, body);

  // Springs with a solved end: forces and the h^2 H v term of the right-hand side (H = k I per
  // spring). The others only add their (constant) energy to the start state's.
  double spring_energy = spring_pass(*sys, body, h, energy_out != nullptr);

  // Volume term (explicit): p dV/dx_i, p = K (V0 - V) / V0. 6 dV/dx_i is the sum over the
  // triangles around i of x_j x x_k; around a closed fan that equals the sum of the triangles'
  // area vectors (x_j - x_i) x (x_k - x_i) (the x_i x (x_k - x_j) terms telescope to zero), the
  // same vector for all three corners: one cross product per triangle instead of three. The
  // volume comes out of the same pass (x_0 . N = x_0 . (x_1 x x_2)). The term applies to closed
  // bodies only, whose fans are closed.
  double p6 = 0.0, volume_energy = 0.0;
  const bool volume_term = body.closed() && body.rest_volume_m3() > 0.0;
  if (volume_term) {
    grad_.assign(n, glm::dvec3(0.0));
    const auto& tri = body.triangles();
    const std::uint32_t* idx = tri.indices.data();
    const std::size_t nt = tri.size();
    // Plain scalars: with glm temporaries GCC spilled the cross product to the stack as one
    // 16-byte and one 8-byte store and read it back across both (a failed store-to-load
    // forward, about a fifth of this function's time on the Zen 1 machine).
    static_assert(sizeof(glm::dvec3) == 3 * sizeof(double));
    const double* xs = &x[0].x;
    double* gs = &grad_[0].x;
    double six_v = 0.0;
    for (std::size_t t = 0; t < nt; ++t) {
      const std::size_t i0 = 3 * std::size_t(idx[3 * t]), i1 = 3 * std::size_t(idx[3 * t + 1]),
                        i2 = 3 * std::size_t(idx[3 * t + 2]);
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
    const double volume = body.orientation() * (six_v / 6.0);  // as SoftBody::volume_m3()
    const double v0 = body.rest_volume_m3();
    // volume_m3() is measured outward whatever the faces' winding; the gradient follows it.
    p6 = body.orientation() * mat.bulk_modulus_Pa * (v0 - volume) / v0 / 6.0;
    volume_energy = 0.5 * mat.bulk_modulus_Pa * (volume - v0) * (volume - v0) / v0;
  }
  p6_ = p6;
  // Sleeping aggregates whose residual can now exceed the tolerance wake; the forces are taken
  // again over the larger awake region.
  if (st.asleep > 0 && wake_by_forces(st, *sys, body, options, p6)) {
    sys = &system(st, body);
    spring_energy = spring_pass(*sys, body, h, energy_out != nullptr);
  }
  if (energy_out) *energy_out = kinetic + potential + spring_energy + volume_energy;
  const std::size_t nf = sys->vertex.size();
  const std::uint32_t* vertex = sys->vertex.data();
  const std::uint32_t* full_compact = st.full.compact.data();
  const std::uint32_t* full_agg = st.full.agg.data();

  // The right-hand side and the diagonal over the free vertices, four lanes per vertex
  // (x, y, z and a zero pad: the loops below run on whole vectors the compiler vectorises).
  // The matrix: diagonal m (1 + h a) + sum of the spring weights, weights h^2 k + h c per class.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h2 * st.k_class[k] + h * c;
  const std::size_t n4 = 4 * nf;
  const std::uint32_t* row = sys->row.data();
  const std::uint32_t* fixed = sys->fixed_count.data();
  rhs_.assign(n4, 0.0);
  diag_.resize(nf);
  self_.resize(nf);
  inv_diag_.assign(n4, 1.0);
  double weight2 = 0.0;  // sum of the free vertices' squared masses, for the absolute tolerance
  // Per aggregate, for sleeping: the sums over its vertices of the squared residual force and
  // pressure gradient.
  std::fill(st.step_residual.begin(), st.step_residual.end(), 0.0);
  std::fill(st.step_gradient.begin(), st.step_gradient.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t i = vertex[ci];
    glm::dvec3 f = m[i] * g + fext[i] - drag * m[i] * v[i] + f_[i];
    if (volume_term) f += p6 * grad_[i];
    {
      const std::uint32_t A = full_agg[full_compact[i]];
      st.step_residual[A] += glm::dot(f, f);
      if (volume_term) st.step_gradient[A] += glm::dot(grad_[i], grad_[i]);
      // A loaded vertex does not sleep (the load is applied again step after step).
      if (fext[i] != glm::dvec3(0.0)) st.step_residual[A] = kNeverQuiet;
    }
    rhs_[4 * ci] = h * f.x;
    rhs_[4 * ci + 1] = h * f.y;
    rhs_[4 * ci + 2] = h * f.z;
    double self = m[i] * (1.0 + h * drag), nbr = 0.0;
    for (std::size_t k = 0; k < 4; ++k) {
      self += double(fixed[4 * ci + k]) * w[k];
      nbr += double(row[4 * ci + k + 1] - row[4 * ci + k]) * w[k];
    }
    const double d = self + nbr;
    self_[ci] = self;
    diag_[ci] = d;
    inv_diag_[4 * ci] = d;  // scratch: the diagonal with the contact blocks, inverted below
    inv_diag_[4 * ci + 1] = d;
    inv_diag_[4 * ci + 2] = d;
    weight2 += m[i] * m[i];
  }
  // Contacts: k n n^T blocks on the diagonal, their h^2 H v term on the right-hand side.
  contacts_.clear();
  for (const SoftBody::ContactTerm& ct : body.contacts()) {
    const std::uint32_t i = ct.vertex;
    if (i >= n || !free_[i]) continue;
    const std::uint32_t ci = sys->compact[i];
    st.step_residual[full_agg[full_compact[i]]] = kNeverQuiet;
    const double kc = h2 * ct.stiffness_N_per_m;
    const glm::dvec3 nn = ct.normal;
    contacts_.insert(contacts_.end(), {double(ci), nn.x, nn.y, nn.z, kc});
    const double nv = kc * glm::dot(nn, v[i]);
    rhs_[4 * ci] -= nv * nn.x;
    rhs_[4 * ci + 1] -= nv * nn.y;
    rhs_[4 * ci + 2] -= nv * nn.z;
    inv_diag_[4 * ci] += kc * nn.x * nn.x;
    inv_diag_[4 * ci + 1] += kc * nn.y * nn.y;
    inv_diag_[4 * ci + 2] += kc * nn.z * nn.z;
  }
  for (std::size_t ci = 0; ci < nf; ++ci) {
    double* di = &inv_diag_[4 * ci];
    const bool ok = di[0] > 0.0 && di[1] > 0.0 && di[2] > 0.0;
    di[0] = ok ? 1.0 / di[0] : 1.0;
    di[1] = ok ? 1.0 / di[1] : 1.0;
    di[2] = ok ? 1.0 / di[2] : 1.0;
  }

  // The solve, warm-started with the last step's dv. It stops at the relative tolerance or when
  // the residual force is below the absolute one (see IntegratorOptions).
  auto& warm = body.warm_start();
  dv_.assign(n4, 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const glm::dvec3 w0 = warm[vertex[ci]];
    dv_[4 * ci] = w0.x;
    dv_[4 * ci + 1] = w0.y;
    dv_[4 * ci + 2] = w0.z;
  }
  const double g2 = glm::dot(g, g);
  const double frac2 = options.cg_weight_fraction * options.cg_weight_fraction;
  const double floor2 = options.cg_force_floor_N * options.cg_force_floor_N;
  const double abs_tol2 = h2 * (frac2 * g2 * weight2 + floor2 * double(nf));
  const double rel_tol2 = options.cg_relative_tolerance * options.cg_relative_tolerance;
  // float reaches a relative residual of about 1e-6 (its rounding of b and A p): below 1e-5
  // the solve runs in double.
  if (options.cg_coarse_level) {
    update_coarse(*sys, st, body, h);
  } else {
    sys->coarse_h = -1.0;  // keeps solve() on Jacobi alone
  }
  if (options.cg_relative_tolerance >= 1e-5) {
    solve<float>(*sys, w, options.max_cg_iterations, rel_tol2, abs_tol2, stats);
  } else {
    solve<double>(*sys, w, options.max_cg_iterations, rel_tol2, abs_tol2, stats);
  }

  // v += dv (solved vertices only), x += h v (every vertex with mass); the warm start keeps dv.
  // Per aggregate, for sleeping: the sum over its vertices of the squared force that one more
  // step at their speed would add to their residual (the diagonal, inertia and springs, times
  // the speed over h): a vertex stopped while it moves that much was not at rest.
  std::fill(warm.begin(), warm.end(), glm::dvec3(0.0));
  std::fill(st.step_speed.begin(), st.step_speed.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t i = vertex[ci];
    const glm::dvec3 d(dv_[4 * ci], dv_[4 * ci + 1], dv_[4 * ci + 2]);
    warm[i] = d;
    v[i] += d;
    const std::uint32_t A = full_agg[full_compact[i]];
    const double stop = diag_[ci] / h;
    st.step_speed[A] += stop * stop * glm::dot(v[i], v[i]);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (m[i] <= 0.0) continue;
    x[i] += h * v[i];
  }
  return *sys;
}

}  // namespace bisturi::sim
