#include "bisturi/sim/integrator.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kIndexMask = (1u << 30) - 1u;
constexpr std::uint32_t kNotFree = std::numeric_limits<std::uint32_t>::max();
constexpr std::size_t kMaxStructures = 16;

/// Spring forces (with the h^2 H v term of the right-hand side divided by h) accumulated into
/// f, which must start at zero; returns the springs' elastic energy when Energy is set.
template <bool Energy>
double spring_pass(const std::uint32_t* a, const std::uint32_t* b, const double* rest,
                   const double* k, std::size_t ns, const glm::dvec3* x, const glm::dvec3* v,
                   double c, double h, glm::dvec3* f) {
  double elastic = 0.0;
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ia = a[s], ib = b[s];
    const double dx = x[ib].x - x[ia].x, dy = x[ib].y - x[ia].y, dz = x[ib].z - x[ia].z;
    const double vx = v[ib].x - v[ia].x, vy = v[ib].y - v[ia].y, vz = v[ib].z - v[ia].z;
    const double len = std::sqrt(dx * dx + dy * dy + dz * dz);
    const double inv = len > 1e-12 ? 1.0 / len : 0.0;
    const double ks = k[s];
    const double stretch = len - rest[s];
    // (k stretch + c u . vrel) u with u = d / len, written on d: one scale for all three.
    const double along = (ks * stretch + c * (dx * vx + dy * vy + dz * vz) * inv) * inv;
    const double hk = h * ks;  // h f + h^2 H v, divided by h below
    const double fx = along * dx + hk * vx, fy = along * dy + hk * vy, fz = along * dz + hk * vz;
    f[ia].x += fx;
    f[ia].y += fy;
    f[ia].z += fz;
    f[ib].x -= fx;
    f[ib].y -= fy;
    f[ib].z -= fz;
    if constexpr (Energy) elastic += 0.5 * ks * stretch * stretch;
  }
  return elastic;
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
  st.k_sum = std::vector<double>(n, 0.0);
  st.degree = std::vector<double>(n, 0.0);
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
    st.k_sum[sp.a] += sp.k_N_per_m;
    st.k_sum[sp.b] += sp.k_N_per_m;
    st.degree[sp.a] += 1.0;
    st.degree[sp.b] += 1.0;
  }
  structures_.push_back(std::move(st));
  return structures_.back();
}

void ImplicitIntegrator::update_free_rows(Structure& st, const std::vector<std::uint8_t>& mask) {
  if (st.free_mask == mask && !st.row.empty()) return;
  st.free_mask = mask;
  const std::size_t n = mask.size();
  st.vertex.clear();
  st.compact.assign(n, kNotFree);
  for (std::size_t i = 0; i < n; ++i) {
    if (mask[i]) {
      st.compact[i] = static_cast<std::uint32_t>(st.vertex.size());
      st.vertex.push_back(static_cast<std::uint32_t>(i));
    }
  }
  const std::size_t nf = st.vertex.size();
  // Four segments per row, one per stiffness class (segment 4 r + class), each in spring order:
  // the product sums a segment's neighbours and scales the sum once by the class's weight.
  st.row.assign(4 * nf + 1, 0);
  const std::size_t ns = st.a.size();
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ca = st.compact[st.a[s]], cb = st.compact[st.b[s]];
    if (ca == kNotFree || cb == kNotFree) continue;
    ++st.row[4 * ca + st.spring_class[s] + 1];
    ++st.row[4 * cb + st.spring_class[s] + 1];
  }
  for (std::size_t i = 0; i < 4 * nf; ++i)
    st.row[i + 1] += st.row[i];
  st.col.resize(st.row[4 * nf]);
  std::vector<std::uint32_t> fill(st.row.begin(), st.row.end() - 1);
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ca = st.compact[st.a[s]], cb = st.compact[st.b[s]];
    if (ca == kNotFree || cb == kNotFree) continue;
    st.col[fill[4 * ca + st.spring_class[s]]++] = cb;
    st.col[fill[4 * cb + st.spring_class[s]]++] = ca;
  }
}

StepStats ImplicitIntegrator::step(SoftBody& body, const IntegratorOptions& options,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step_index) {
  StepStats stats;
  body.refresh_topology();
  if (body.frozen()) {
    body.clear_forces();
    stats.frozen = true;
    return stats;
  }
  Structure& st = structure(body);
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

  for (int attempt = 0; attempt <= options.max_retry_halvings; ++attempt) {
    const int substeps = 1 << attempt;
    const double h = options.dt_s / substeps;
    StepStats trial;
    trial.substeps = substeps;
    for (int s = 0; s < substeps; ++s) {
      // The energy of the start state comes out of the first substep's force pass for free.
      double* energy_out = (attempt == 0 && s == 0 && energy_check) ? &energy_before : nullptr;
      substep(body, st, options, h, double(s + 1) / substeps, trial, energy_out);
    }
    const std::string reason = check(body, st, options, energy_before, energy_check);
    if (reason.empty()) {
      trial.rolled_back = attempt > 0;
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

double ImplicitIntegrator::elastic(const SoftBody& body, const Structure& st) {
  const glm::dvec3* x = body.positions().data();
  const std::uint32_t* a = st.a.data();
  const std::uint32_t* b = st.b.data();
  const double* rest = st.rest.data();
  const double* k = st.k.data();
  double e = 0.0;
  const std::size_t ns = st.a.size();
  for (std::size_t s = 0; s < ns; ++s) {
    const double dx = x[b[s]].x - x[a[s]].x, dy = x[b[s]].y - x[a[s]].y, dz = x[b[s]].z - x[a[s]].z;
    const double stretch = std::sqrt(dx * dx + dy * dy + dz * dz) - rest[s];
    e += 0.5 * k[s] * stretch * stretch;
  }
  if (body.closed() && body.rest_volume_m3() > 0.0) {
    const double dv = body.volume_m3() - body.rest_volume_m3();
    e += 0.5 * body.material().bulk_modulus_Pa * dv * dv / body.rest_volume_m3();
  }
  return e;
}

std::string ImplicitIntegrator::check(const SoftBody& body, const Structure& st,
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
  const double energy_after = kinetic + potential + elastic(body, st);
  if (!std::isfinite(energy_after)) return "non-finite energy";
  const double allowed = std::max(0.0, work) + options.energy_jump_J +
                         options.energy_jump_relative * std::abs(energy_before);
  if (energy_after - energy_before > allowed) {
    return "energy rose by " + std::to_string(energy_after - energy_before) + " J (allowed " +
           std::to_string(allowed) + " J)";
  }
  return {};
}

void ImplicitIntegrator::substep(SoftBody& body, Structure& st, const IntegratorOptions& options,
                                 double h, double fraction, StepStats& stats, double* energy_out) {
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
  free_.resize(n);
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
    if (energy_out) {
      kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
      potential -= m[i] * glm::dot(g, x[i]);
    }
  }
  update_free_rows(st, free_);
  const std::size_t nf = st.vertex.size();
  const std::uint32_t* vertex = st.vertex.data();

  // Springs: forces and the h^2 H v term of the right-hand side (H = k I per spring).
  f_.assign(n, glm::dvec3(0.0));
  double elastic_energy =
      energy_out ? spring_pass<true>(st.a.data(), st.b.data(), st.rest.data(), st.k.data(),
                                     st.a.size(), x.data(), v.data(), c, h, f_.data())
                 : spring_pass<false>(st.a.data(), st.b.data(), st.rest.data(), st.k.data(),
                                      st.a.size(), x.data(), v.data(), c, h, f_.data());

  // Volume term (explicit): p dV/dx_i, p = K (V0 - V) / V0. One pass over the triangles gives
  // both the volume and the gradient (each corner's cross product is its share of 6 V).
  double p6 = 0.0;
  const bool volume_term = body.closed() && body.rest_volume_m3() > 0.0;
  if (volume_term) {
    grad_.assign(n, glm::dvec3(0.0));
    const auto& tri = body.triangles();
    const std::uint32_t* idx = tri.indices.data();
    const std::size_t nt = tri.size();
    double six_v = 0.0;
    for (std::size_t t = 0; t < nt; ++t) {
      const std::uint32_t i0 = idx[3 * t], i1 = idx[3 * t + 1], i2 = idx[3 * t + 2];
      const glm::dvec3 c0 = glm::cross(x[i1], x[i2]);
      six_v += glm::dot(x[i0], c0);
      grad_[i0] += c0;
      grad_[i1] += glm::cross(x[i2], x[i0]);
      grad_[i2] += glm::cross(x[i0], x[i1]);
    }
    const double volume = body.orientation() * (six_v / 6.0);  // as SoftBody::volume_m3()
    const double v0 = body.rest_volume_m3();
    // volume_m3() is measured outward whatever the faces' winding; the gradient follows it.
    p6 = body.orientation() * mat.bulk_modulus_Pa * (v0 - volume) / v0 / 6.0;
    elastic_energy += 0.5 * mat.bulk_modulus_Pa * (volume - v0) * (volume - v0) / v0;
  }
  if (energy_out) *energy_out = kinetic + potential + elastic_energy;

  // The right-hand side and the diagonal over the free vertices, four lanes per vertex
  // (x, y, z and a zero pad: the loops below run on whole vectors the compiler vectorises).
  // The matrix: diagonal m (1 + h a) + sum of the spring weights, weights h^2 k + h c per class.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h2 * st.k_class[k] + h * c;
  const std::size_t n4 = 4 * nf;
  rhs_.assign(n4, 0.0);
  diag_.resize(nf);
  inv_diag_.assign(n4, 1.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t i = vertex[ci];
    glm::dvec3 f = m[i] * g + fext[i] - drag * m[i] * v[i] + f_[i];
    if (volume_term) f += p6 * grad_[i];
    rhs_[4 * ci] = h * f.x;
    rhs_[4 * ci + 1] = h * f.y;
    rhs_[4 * ci + 2] = h * f.z;
    const double d = m[i] * (1.0 + h * drag) + h2 * st.k_sum[i] + h * c * st.degree[i];
    diag_[ci] = d;
    inv_diag_[4 * ci] = d;  // scratch: the diagonal with the contact blocks, inverted below
    inv_diag_[4 * ci + 1] = d;
    inv_diag_[4 * ci + 2] = d;
  }
  // Contacts: k n n^T blocks on the diagonal, their h^2 H v term on the right-hand side.
  contacts_.clear();
  for (const SoftBody::ContactTerm& ct : body.contacts()) {
    const std::uint32_t i = ct.vertex;
    if (i >= n || !free_[i]) continue;
    const std::uint32_t ci = st.compact[i];
    const double kc = h2 * ct.stiffness_N_per_m;
    const glm::dvec3 nn = ct.normal;
    contacts_.push_back({ci, nn.x, nn.y, nn.z, kc});
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

  const std::uint32_t* row = st.row.data();
  const std::uint32_t* col = st.col.data();
  const double* diag = diag_.data();
  // out = A in; returns in . out (the CG's p . A p comes out of the same pass).
  auto apply = [&](const std::vector<double>& in_v, std::vector<double>& out_v) {
    const double* in = in_v.data();
    double* out = out_v.data();
    double in_out = 0.0;
    for (std::size_t i = 0; i < nf; ++i) {
      const double* pi = in + 4 * i;
      double s0 = diag[i] * pi[0], s1 = diag[i] * pi[1], s2 = diag[i] * pi[2], s3 = diag[i] * pi[3];
      for (std::size_t k = 0; k < 4; ++k) {
        double a0 = 0.0, a1 = 0.0, a2 = 0.0, a3 = 0.0;
        const std::uint32_t end = row[4 * i + k + 1];
        for (std::uint32_t e = row[4 * i + k]; e < end; ++e) {
          const double* nb = in + 4 * std::size_t(col[e]);
          a0 += nb[0];
          a1 += nb[1];
          a2 += nb[2];
          a3 += nb[3];
        }
        s0 -= w[k] * a0;
        s1 -= w[k] * a1;
        s2 -= w[k] * a2;
        s3 -= w[k] * a3;
      }
      double* po = out + 4 * i;
      po[0] = s0;
      po[1] = s1;
      po[2] = s2;
      po[3] = s3;
      in_out += (pi[0] * s0 + pi[1] * s1) + (pi[2] * s2 + pi[3] * s3);
    }
    for (const Contact& ct : contacts_) {
      const double* pi = in + 4 * std::size_t(ct.c);
      const double kn = ct.k * (ct.nx * pi[0] + ct.ny * pi[1] + ct.nz * pi[2]);
      out[4 * ct.c] += kn * ct.nx;
      out[4 * ct.c + 1] += kn * ct.ny;
      out[4 * ct.c + 2] += kn * ct.nz;
      in_out += kn * (ct.nx * pi[0] + ct.ny * pi[1] + ct.nz * pi[2]);
    }
    return in_out;
  };

  // Preconditioned conjugate gradient, warm-started. Three passes per iteration: A p (with
  // p . A p), the update of dv and r (with r . z and r . r), the new direction.
  auto& warm = body.warm_start();
  dv_.assign(n4, 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const glm::dvec3 w0 = warm[vertex[ci]];
    dv_[4 * ci] = w0.x;
    dv_[4 * ci + 1] = w0.y;
    dv_[4 * ci + 2] = w0.z;
  }
  r_.resize(n4);
  p_.resize(n4);
  ap_.resize(n4);
  apply(dv_, ap_);
  double rz = 0.0, r2 = 0.0, b2 = 0.0;
  {
    double* r = r_.data();
    double* p = p_.data();
    const double* rhs = rhs_.data();
    const double* ap = ap_.data();
    const double* inv = inv_diag_.data();
    // One partial sum per lane: the reductions vectorise and keep one fixed order.
    double rz4[4] = {0.0, 0.0, 0.0, 0.0}, r24[4] = {0.0, 0.0, 0.0, 0.0},
           b24[4] = {0.0, 0.0, 0.0, 0.0};
    for (std::size_t i = 0; i < n4; i += 4) {
      for (std::size_t l = 0; l < 4; ++l) {
        const std::size_t e = i + l;
        r[e] = rhs[e] - ap[e];
        p[e] = r[e] * inv[e];
        rz4[l] += r[e] * p[e];
        r24[l] += r[e] * r[e];
        b24[l] += rhs[e] * rhs[e];
      }
    }
    rz = (rz4[0] + rz4[1]) + (rz4[2] + rz4[3]);
    r2 = (r24[0] + r24[1]) + (r24[2] + r24[3]);
    b2 = (b24[0] + b24[1]) + (b24[2] + b24[3]);
  }
  b2 = std::max(b2, 1e-300);
  const double tol2 = options.cg_relative_tolerance * options.cg_relative_tolerance * b2;
  int it = 0;
  while (it < options.max_cg_iterations && r2 > tol2) {
    const double pap = apply(p_, ap_);
    if (!(pap > 0.0)) break;
    const double alpha = rz / pap;
    double rz_new = 0.0;
    r2 = 0.0;
    {
      double* dv = dv_.data();
      double* r = r_.data();
      const double* p = p_.data();
      const double* ap = ap_.data();
      const double* inv = inv_diag_.data();
      double rz4[4] = {0.0, 0.0, 0.0, 0.0}, r24[4] = {0.0, 0.0, 0.0, 0.0};
      for (std::size_t i = 0; i < n4; i += 4) {
        for (std::size_t l = 0; l < 4; ++l) {
          const std::size_t e = i + l;
          dv[e] += alpha * p[e];
          r[e] -= alpha * ap[e];
          rz4[l] += r[e] * r[e] * inv[e];
          r24[l] += r[e] * r[e];
        }
      }
      rz_new = (rz4[0] + rz4[1]) + (rz4[2] + rz4[3]);
      r2 = (r24[0] + r24[1]) + (r24[2] + r24[3]);
    }
    ++it;
    if (it >= options.max_cg_iterations || r2 <= tol2) break;  // no direction needed
    const double beta = rz_new / rz;
    rz = rz_new;
    double* p = p_.data();
    const double* r = r_.data();
    const double* inv = inv_diag_.data();
    for (std::size_t e = 0; e < n4; ++e)
      p[e] = r[e] * inv[e] + beta * p[e];
  }
  stats.cg_iterations += it;
  stats.relative_residual = std::sqrt(r2 / b2);

  // v += dv (free vertices only), x += h v (every vertex with mass); the warm start keeps dv.
  std::fill(warm.begin(), warm.end(), glm::dvec3(0.0));
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const glm::dvec3 d(dv_[4 * ci], dv_[4 * ci + 1], dv_[4 * ci + 2]);
    warm[vertex[ci]] = d;
    v[vertex[ci]] += d;
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (m[i] <= 0.0) continue;
    x[i] += h * v[i];
  }
}

}  // namespace bisturi::sim
