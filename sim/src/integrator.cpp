#include "bisturi/sim/integrator.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kClassShift = 30;
constexpr std::uint32_t kIndexMask = (1u << kClassShift) - 1u;
constexpr std::size_t kMaxStructures = 16;

inline double dot_all(const std::vector<glm::dvec3>& a, const std::vector<glm::dvec3>& b) {
  double s = 0.0;
  for (std::size_t i = 0; i < a.size(); ++i)
    s += glm::dot(a[i], b[i]);
  return s;
}

}  // namespace

const ImplicitIntegrator::Structure& ImplicitIntegrator::structure(const SoftBody& body) {
  const std::uint64_t generation = body.derived_generation();
  for (const Structure& s : structures_) {
    if (s.generation == generation) return s;
  }
  if (structures_.size() >= kMaxStructures) structures_.erase(structures_.begin());
  Structure st;
  st.generation = generation;
  const auto& springs = body.springs();
  const std::size_t n = body.positions().size();
  if (n > kIndexMask) throw SimInputError("integrator: more than 2^30 vertex slots");
  st.a.reserve(springs.size());
  st.b.reserve(springs.size());
  st.rest.reserve(springs.size());
  st.k.reserve(springs.size());
  std::vector<std::uint32_t> spring_class(springs.size(), 0);
  std::size_t classes = 0;
  st.row.assign(n + 1, 0);
  st.k_sum = std::vector<double>(n, 0.0);
  st.degree = std::vector<double>(n, 0.0);
  for (std::size_t s = 0; s < springs.size(); ++s) {
    const Spring& sp = springs[s];
    st.a.push_back(sp.a);
    st.b.push_back(sp.b);
    st.rest.push_back(sp.rest_m);
    st.k.push_back(sp.k_N_per_m);
    // Springs come in a few stiffness classes (one per kind): the rows store the class.
    std::size_t c = 0;
    while (c < classes && st.k_class[c] != sp.k_N_per_m)
      ++c;
    if (c == classes) {
      if (classes == 4) throw SimInputError("integrator: more than four spring stiffnesses");
      st.k_class[classes++] = sp.k_N_per_m;
    }
    spring_class[s] = static_cast<std::uint32_t>(c);
    ++st.row[sp.a + 1];
    ++st.row[sp.b + 1];
    st.k_sum[sp.a] += sp.k_N_per_m;
    st.k_sum[sp.b] += sp.k_N_per_m;
    st.degree[sp.a] += 1.0;
    st.degree[sp.b] += 1.0;
  }
  for (std::size_t i = 0; i < n; ++i)
    st.row[i + 1] += st.row[i];
  st.col.resize(st.row[n]);
  std::vector<std::uint32_t> fill(st.row.begin(), st.row.end() - 1);
  for (std::size_t s = 0; s < springs.size(); ++s) {
    const std::uint32_t tag = spring_class[s] << kClassShift;
    st.col[fill[springs[s].a]++] = springs[s].b | tag;
    st.col[fill[springs[s].b]++] = springs[s].a | tag;
  }
  structures_.push_back(std::move(st));
  return structures_.back();
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
  const Structure& st = structure(body);
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
    double work = 0.0;
    const auto& f = body.external_forces();
    for (std::size_t i = 0; i < f.size(); ++i)
      work += glm::dot(f[i], x[i] - saved_x_[i]);
    const std::string reason = check(body, st, options, energy_before, work, energy_check);
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

double ImplicitIntegrator::energy(const SoftBody& body, const Structure& st,
                                  const glm::dvec3& gravity) const {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const auto& m = body.masses();
  double kinetic = 0.0, potential = 0.0, elastic = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
    potential -= m[i] * glm::dot(gravity, x[i]);
  }
  for (std::size_t s = 0; s < st.a.size(); ++s) {
    const glm::dvec3 d = x[st.b[s]] - x[st.a[s]];
    const double stretch = std::sqrt(glm::dot(d, d)) - st.rest[s];
    elastic += 0.5 * st.k[s] * stretch * stretch;
  }
  if (body.closed() && body.rest_volume_m3() > 0.0) {
    const double dv = body.volume_m3() - body.rest_volume_m3();
    elastic += 0.5 * body.material().bulk_modulus_Pa * dv * dv / body.rest_volume_m3();
  }
  return kinetic + elastic + potential;
}

std::string ImplicitIntegrator::check(const SoftBody& body, const Structure& st,
                                      const IntegratorOptions& options, double energy_before,
                                      double external_work, bool energy_check) const {
  if (!std::isfinite(external_work)) return "non-finite external force";
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const double max_speed2 = options.max_speed_m_s * options.max_speed_m_s;
  double sum = 0.0, fastest = 0.0;
  for (std::size_t i = 0; i < x.size(); ++i) {
    sum += x[i].x + x[i].y + x[i].z + v[i].x + v[i].y + v[i].z;
    fastest = std::max(fastest, glm::dot(v[i], v[i]));
  }
  if (!std::isfinite(sum) || !std::isfinite(fastest)) {
    for (std::size_t i = 0; i < x.size(); ++i) {
      const double s = x[i].x + x[i].y + x[i].z + v[i].x + v[i].y + v[i].z;
      if (!std::isfinite(s)) return "non-finite state at vertex " + std::to_string(i);
    }
    return "non-finite state";
  }
  if (fastest > max_speed2) {
    for (std::size_t i = 0; i < x.size(); ++i) {
      if (glm::dot(v[i], v[i]) > max_speed2) {
        return "vertex " + std::to_string(i) + " faster than " +
               std::to_string(options.max_speed_m_s) + " m/s";
      }
    }
  }
  if (!energy_check) return {};
  const double energy_after = energy(body, st, options.gravity_m_s2);
  if (!std::isfinite(energy_after)) return "non-finite energy";
  const double allowed = std::max(0.0, external_work) + options.energy_jump_J +
                         options.energy_jump_relative * std::abs(energy_before);
  if (energy_after - energy_before > allowed) {
    return "energy rose by " + std::to_string(energy_after - energy_before) + " J (allowed " +
           std::to_string(allowed) + " J)";
  }
  return {};
}

void ImplicitIntegrator::substep(SoftBody& body, const Structure& st,
                                 const IntegratorOptions& options, double h, double fraction,
                                 StepStats& stats, double* energy_out) {
  auto& x = body.positions();
  auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const Material& mat = body.material();
  const std::size_t n = x.size();
  const double drag = mat.drag_per_s;
  const double c = mat.spring_damping_N_s_per_m;
  const glm::dvec3 g = options.gravity_m_s2;
  free_.resize(n);
  f_.resize(n);
  rhs_.assign(n, glm::dvec3(0.0));
  double kinetic = 0.0, potential = 0.0, elastic = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    free_[i] = 1;
    if (m[i] <= 0.0 || body.anchored(vi)) {
      free_[i] = 0;
      v[i] = glm::dvec3(0.0);
    } else if (body.kinematic(vi)) {
      free_[i] = 0;
      // The target is reached at the end of the step; substeps follow the straight line.
      const glm::dvec3 goal = saved_x_[i] + (body.kinematic_target(vi) - saved_x_[i]) * fraction;
      v[i] = (goal - x[i]) / h;
    }
    f_[i] = free_[i] ? m[i] * g + fext[i] - drag * m[i] * v[i] : glm::dvec3(0.0);
    if (energy_out) {
      kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
      potential -= m[i] * glm::dot(g, x[i]);
    }
  }

  // Springs: forces and the h^2 H v term of the right-hand side (H = k I per spring).
  const std::size_t ns = st.a.size();
  const double h2 = h * h;
  for (std::size_t s = 0; s < ns; ++s) {
    const std::uint32_t ia = st.a[s], ib = st.b[s];
    const glm::dvec3 d = x[ib] - x[ia];
    const double len = std::sqrt(glm::dot(d, d));
    const double k = st.k[s];
    const glm::dvec3 vrel = v[ib] - v[ia];
    const double stretch = len - st.rest[s];
    glm::dvec3 force(0.0);
    if (len > 1e-12) {
      const glm::dvec3 u = d * (1.0 / len);
      force = (k * stretch + c * glm::dot(u, vrel)) * u;
    }
    const glm::dvec3 hv = (h2 * k) * vrel;
    f_[ia] += force + (1.0 / h) * hv;  // h f + h^2 H v, divided by h below
    f_[ib] -= force + (1.0 / h) * hv;
    elastic += 0.5 * k * stretch * stretch;
  }

  // Volume term (explicit): p dV/dx_i, p = K (V0 - V) / V0.
  if (body.closed() && body.rest_volume_m3() > 0.0) {
    const double volume = body.volume_m3();
    const double v0 = body.rest_volume_m3();
    // volume_m3() is measured outward whatever the faces' winding; the gradient follows it.
    const double p = body.orientation() * mat.bulk_modulus_Pa * (v0 - volume) / v0;
    const auto& tri = body.triangles();
    for (std::size_t t = 0; t < tri.size(); ++t) {
      const std::uint32_t i0 = tri.indices[3 * t], i1 = tri.indices[3 * t + 1],
                          i2 = tri.indices[3 * t + 2];
      f_[i0] += (p / 6.0) * glm::cross(x[i1], x[i2]);
      f_[i1] += (p / 6.0) * glm::cross(x[i2], x[i0]);
      f_[i2] += (p / 6.0) * glm::cross(x[i0], x[i1]);
    }
    elastic += 0.5 * mat.bulk_modulus_Pa * (volume - v0) * (volume - v0) / v0;
  }
  if (energy_out) *energy_out = kinetic + potential + elastic;

  // The matrix: diagonal m (1 + h a) + sum of the spring weights, weights h^2 k + h c per class.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h2 * st.k_class[k] + h * c;
  diag_.resize(n);
  inv_diag_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    diag_[i] = m[i] * (1.0 + h * drag) + h2 * st.k_sum[i] + h * c * st.degree[i];
    rhs_[i] = free_[i] ? h * f_[i] : glm::dvec3(0.0);
    inv_diag_[i] = glm::dvec3(1.0);
  }
  // Contacts: k n n^T blocks on the diagonal, their h^2 H v term on the right-hand side.
  const auto& contacts = body.contacts();
  for (const SoftBody::ContactTerm& ct : contacts) {
    const std::uint32_t i = ct.vertex;
    if (i >= n || !free_[i]) continue;
    const double kc = h2 * ct.stiffness_N_per_m;
    rhs_[i] -= (kc * glm::dot(ct.normal, v[i])) * ct.normal;
  }
  {
    std::vector<glm::dvec3>& d3 = ap_;  // scratch: the diagonal with the contact blocks
    d3.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      d3[i] = glm::dvec3(diag_[i]);
    for (const SoftBody::ContactTerm& ct : contacts) {
      if (ct.vertex < n) d3[ct.vertex] += h2 * ct.stiffness_N_per_m * ct.normal * ct.normal;
    }
    for (std::size_t i = 0; i < n; ++i) {
      if (free_[i] && d3[i].x > 0.0 && d3[i].y > 0.0 && d3[i].z > 0.0) inv_diag_[i] = 1.0 / d3[i];
    }
  }

  const std::uint32_t* row = st.row.data();
  const std::uint32_t* col = st.col.data();
  // out = A in; returns in . out (the CG's p . A p comes out of the same pass).
  auto apply = [&](const std::vector<glm::dvec3>& in, std::vector<glm::dvec3>& out) {
    double in_out = 0.0;
    for (std::size_t i = 0; i < n; ++i) {
      if (!free_[i]) {
        out[i] = glm::dvec3(0.0);
        continue;
      }
      glm::dvec3 s = diag_[i] * in[i];
      for (std::uint32_t e = row[i]; e < row[i + 1]; ++e) {
        const std::uint32_t packed = col[e];
        s -= w[packed >> kClassShift] * in[packed & kIndexMask];
      }
      out[i] = s;
      in_out += glm::dot(in[i], s);
    }
    for (const SoftBody::ContactTerm& ct : contacts) {
      const std::uint32_t i = ct.vertex;
      if (i >= n || !free_[i]) continue;
      const double kn = h2 * ct.stiffness_N_per_m * glm::dot(ct.normal, in[i]);
      out[i] += kn * ct.normal;
      in_out += kn * glm::dot(ct.normal, in[i]);
    }
    return in_out;
  };

  // Preconditioned conjugate gradient, warm-started. Three passes per iteration: A p (with
  // p . A p), the update of dv and r (with r . z and r . r), the new direction.
  auto& warm = body.warm_start();
  dv_.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    dv_[i] = free_[i] ? warm[i] : glm::dvec3(0.0);
  r_.resize(n);
  p_.resize(n);
  ap_.resize(n);
  apply(dv_, ap_);
  double rz = 0.0, r2 = 0.0, b2 = 0.0;
  for (std::size_t i = 0; i < n; ++i) {
    r_[i] = rhs_[i] - ap_[i];
    p_[i] = r_[i] * inv_diag_[i];
    rz += glm::dot(r_[i], p_[i]);
    r2 += glm::dot(r_[i], r_[i]);
    b2 += glm::dot(rhs_[i], rhs_[i]);
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
    for (std::size_t i = 0; i < n; ++i) {
      dv_[i] += alpha * p_[i];
      r_[i] -= alpha * ap_[i];
      rz_new += glm::dot(r_[i], r_[i] * inv_diag_[i]);
      r2 += glm::dot(r_[i], r_[i]);
    }
    ++it;
    if (it >= options.max_cg_iterations || r2 <= tol2) break;  // no direction needed
    const double beta = rz_new / rz;
    rz = rz_new;
    for (std::size_t i = 0; i < n; ++i)
      p_[i] = r_[i] * inv_diag_[i] + beta * p_[i];
  }
  stats.cg_iterations += it;
  stats.relative_residual = std::sqrt(r2 / b2);

  for (std::size_t i = 0; i < n; ++i) {
    if (m[i] <= 0.0) continue;
    v[i] += dv_[i];
    x[i] += h * v[i];
  }
  warm = dv_;
}

}  // namespace bisturi::sim
