// The implicit integrator's step (integrator.h, docs/sim/integrator.md): constraints, spring and
// volume passes, the right-hand side, the CG solve, the update and the divergence guard. The
// solver structure it solves with is made in integrator_system.cpp, sleeping is in
// integrator_sleep.cpp.

#include "bisturi/sim/integrator.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <memory>
#include <type_traits>

#include <glm/geometric.hpp>

#include "cg_solver.h"
#include "integrator_shared.h"
#include "integrator_state.h"
#include "spring_kernels.h"
#include "step_threads.h"
#include "volume_kernels.h"

namespace bisturi::sim {

// The helpers the integrator's files share (integrator_shared.h).
using namespace integrator_detail;  // NOLINT(google-build-using-namespace)

namespace {

constexpr double kNeverQuiet = std::numeric_limits<double>::infinity();

/// The array team member t accumulates into: `first` (zeroed by the caller) for member 0, its
/// own zeroed array of the same size for the others.
glm::dvec3* member_array(std::vector<glm::dvec3>& first,
                         std::vector<std::vector<glm::dvec3>>& others, unsigned t) {
  if (t == 0 || others.empty()) return first.data();  // a sequential team shares `first`
  others[t - 1].assign(first.size(), glm::dvec3(0.0));
  return others[t - 1].data();
}

}  // namespace

ImplicitIntegrator::ImplicitIntegrator() : impl_(std::make_unique<ImplicitEulerState>()) {}
ImplicitIntegrator::~ImplicitIntegrator() = default;
ImplicitIntegrator::ImplicitIntegrator(ImplicitIntegrator&&) noexcept = default;
ImplicitIntegrator& ImplicitIntegrator::operator=(ImplicitIntegrator&&) noexcept = default;

StepStats ImplicitIntegrator::step(SoftBody& body, const IntegratorOptions& options,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step) {
  return impl_->step(body, options, events, body_index, step);
}
void ImplicitIntegrator::prepare(SoftBody& body, const IntegratorOptions& options) {
  impl_->prepare(body, options);
}
void ImplicitIntegrator::wake(const SoftBody& body) {
  impl_->wake(body);
}
std::string ImplicitIntegrator::check_free_system(const SoftBody& body) {
  return impl_->check_free_system(body);
}
std::uint64_t ImplicitIntegrator::systems_updated() const {
  return impl_->systems_updated_;
}

void ImplicitEulerState::free_mask(const SoftBody& body) {
  const auto& m = body.masses();
  const std::size_t n = m.size();
  free_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId vi(static_cast<std::uint32_t>(i));
    free_[i] = (m[i] <= 0.0 || body.anchored(vi) || body.kinematic(vi)) ? 0 : 1;
  }
}

void ImplicitEulerState::prepare(SoftBody& body, const IntegratorOptions& options) {
  body.refresh_topology();
  Structure& st = structure(body);
  free_mask(body);
  update_free_rows(st, free_, body.masses());
  if (options.cg_coarse_level) update_coarse(st.full, st, body, options.dt_s);
  // Multirate: the far field's copy and its solver now, not in the next step (tens of
  // milliseconds at 20k vertices, which would hold that step up).
  if (options.far_field_interval > 1 && body.kinematic_count() == 0) far_reset(st, body, options);
  // Scratch at its working size, so the first step allocates nothing.
  const std::size_t n = body.positions().size();
  const std::size_t n4 = 4 * st.full.vertex.size();
  saved_x_.reserve(n);
  saved_v_.reserve(n);
  f_.reserve(n);
  grad_.reserve(n);
  for (auto* vec : {&rhs_, &dv_})
    vec->reserve(n4);
  fbuf_.reserve(4 * n4);
  dbuf_.reserve(3 * n4);
}

StepStats ImplicitEulerState::step(SoftBody& body, const IntegratorOptions& options,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step_index) {
  StepStats stats;
  step_team_ = team(options);
  bound_hessian_ = options.spring_hessian == SpringHessian::Bound;
  body.refresh_topology();
  if (body.frozen()) {
    body.clear_forces();
    stats.frozen = true;
    return stats;
  }
  Structure& st = structure(body);
  if (options.far_field_interval > 1) {
    if (std::optional<StepStats> multirate =
            step_multirate(body, st, options, events, body_index, step_index)) {
      return *multirate;
    }
  }
  st.multirate.groups.valid = false;  // a single-rate step moves every group
  if (options.sleeping && sleeps_entirely(st, body)) {
    stats.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
    body.clear_forces();
    return stats;
  }
  // Read before the non-const views below count as edits.
  const bool untouched =
      st.ahead.valid && st.ahead.state_edits == body.state_edits() && st.ahead.members == members();
  st.ahead.valid = false;
  auto& x = body.positions();
  auto& v = body.velocities();
  saved_x_ = x;
  saved_v_ = v;
  checkpoint();
  const bool any_kinematic = body.kinematic_count() > 0;
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
                     first ? &energy_before : nullptr, first && untouched);
      checkpoint();
    }
    const double elastic_after = energy_check ? end_pass(st, *sys, body, options) : 0.0;
    checkpoint();
    const std::string reason = check(body, options, energy_before, energy_check, elastic_after);
    if (reason.empty()) {
      trial.rolled_back = attempt > 0;
      trial.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
      trial.awake_vertices = static_cast<std::uint32_t>(sys->vertex.size());
      if (options.sleeping && !any_kinematic && attempt == 0) update_sleep(st, body, options);
      body.clear_forces();
      // Sleep changes show as a new system id; edits from now on as a new count.
      st.ahead.valid = energy_check;
      st.ahead.state_edits = body.state_edits();
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

std::string ImplicitEulerState::check(const SoftBody& body, const IntegratorOptions& options,
                                      double energy_before, bool energy_check, double elastic_after,
                                      const std::vector<std::uint32_t>* only) const {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const glm::dvec3 g = options.gravity_m_s2;
  const double max_speed2 = options.max_speed_m_s * options.max_speed_m_s;
  // The vertices swept: all, or `only`.
  const std::size_t n = only != nullptr ? only->size() : x.size();
  const std::uint32_t* list = only != nullptr ? only->data() : nullptr;
  auto vertex = [list](std::size_t k) { return list != nullptr ? std::size_t{list[k]} : k; };
  // One sweep: the external forces' work over the step, finiteness, the fastest vertex and the
  // kinetic and gravitational energies.
  double work = 0.0, sum = 0.0, fastest = 0.0, kinetic = 0.0, potential = 0.0;
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t i = vertex(k);
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
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = vertex(k);
      const double s = x[i].x + x[i].y + x[i].z + v[i].x + v[i].y + v[i].z;
      if (!std::isfinite(s)) return "non-finite state at vertex " + std::to_string(i);
    }
    return "non-finite state";
  }
  if (fastest > max_speed2) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t i = vertex(k);
      if (glm::dot(v[i], v[i]) > max_speed2) {
        return "vertex " + std::to_string(i) + " faster than " +
               std::to_string(options.max_speed_m_s) + " m/s";
      }
    }
  }
  if (!energy_check) return {};
  const double energy_after = kinetic + potential + elastic_after;
  if (!std::isfinite(energy_after)) return "non-finite energy";
  const double allowed = std::max(0.0, work) + options.energy_jump_J +
                         options.energy_jump_relative * std::abs(energy_before);
  if (energy_after - energy_before > allowed) {
    return "energy rose by " + std::to_string(energy_after - energy_before) + " J (allowed " +
           std::to_string(allowed) + " J)";
  }
  return {};
}

void ImplicitEulerState::update_diagonal(System& st, const SoftBody& body, double h,
                                         const double (&w)[4]) {
  System::Diagonal& dg = st.diagonal;
  if (dg.system == st.id && dg.h == h && dg.members == members()) return;
  const std::size_t nf = st.vertex.size();
  const std::uint32_t* vertex = st.vertex.data();
  const std::uint32_t* free = st.free_count.data();
  const std::uint32_t* fixed = st.fixed_count.data();
  const auto& m = body.masses();
  const double drag = body.material().drag_per_s;
  dg.value.resize(nf);
  dg.self.resize(nf);
  dg.self_f.resize(nf);
  // The bound matrix's diagonal m (1 + h a) + sum of the spring weights h^2 k + h c (the sleep
  // test's stopping force); the solve's matrix has the mass part and the springs' blocks.
  // Per member the sum of the free vertices' squared masses, for the absolute tolerance.
  std::array<double, kMaxThreads> weight2_part{};
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned t) {
    double weight2 = 0.0;
    for (std::size_t ci = first; ci < last; ++ci) {
      const std::uint32_t i = vertex[ci];
      const double self = m[i] * (1.0 + h * drag);
      double springs = 0.0;
      for (std::size_t k = 0; k < 4; ++k)
        springs += double(fixed[4 * ci + k] + free[4 * ci + k]) * w[k];
      dg.value[ci] = self + springs;
      dg.self[ci] = self;
      dg.self_f[ci] = static_cast<float>(self);
      weight2 += m[i] * m[i];
    }
    weight2_part[t] = weight2;
  });
  dg.weight2 = 0.0;
  for (const double w2 : weight2_part)
    dg.weight2 += w2;
  dg.system = st.id;
  dg.h = h;
  dg.members = members();
}

template <class T>
const T* ImplicitEulerState::solve(System& st, const std::vector<glm::dvec3>& warm, bool warm_start,
                                   int max_iterations, double rel_tol2, double abs_tol2,
                                   StepStats& stats) {
  const std::size_t nf = st.vertex.size();
  const std::size_t n4 = 4 * nf;
  block_rows(st);
  CgData<T> d;
  d.nf = nf;
  d.row = st.prow.data();
  d.col = st.pcol.data();
  d.blk = entry_blocks_.data();
  d.held_blocks = held_blocks_.data();
  d.held = held_blocks_.size() / 5;
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
  System::Diagonal& dg = st.diagonal;
  const T* inv = nullptr;
  if constexpr (std::is_same_v<T, double>) {
    dbuf_.resize(3 * n4);
    dv_.resize(n4);
    inv = jinv_.data();
    d.self = dg.self.data();
    d.b = rhs_.data();
    d.dv = dv_.data();
    d.r = dbuf_.data();
    d.p = d.r + n4;
    d.ap = d.p + n4;
  } else {
    // Layout: r, p, ap, dv, b (4 lanes each).
    fbuf_.resize(5 * n4);
    float* f = fbuf_.data();
    d.r = f;
    d.p = f + n4;
    d.ap = f + 2 * n4;
    d.dv = f + 3 * n4;
    float* b = f + 4 * n4;
    for (std::size_t e = 0; e < n4; ++e)
      b[e] = static_cast<float>(rhs_[e]);
    inv = jinv_f_.data();
    d.self = dg.self_f.data();
    d.b = b;
  }
  // The start: zero, or with warm_start the last step's dv. When the right-hand side already
  // meets the absolute tolerance, the answer is the block-Jacobi one, B^-1 b, with no iteration:
  // not the warm start (applied again step after step it keeps a resting body moving at the
  // tolerance's level), nor zero (the true Hessian has nearly no stiffness across a resting
  // surface, so the velocity left there would never decay: a body at rest kept creeping at
  // 5e-8 m/s and never slept).
  {
    const std::uint32_t* vertex = st.vertex.data();
    const bool small = b2 <= abs_tol2;
    const bool zero = !warm_start;
    const T* binv = inv;
    for (std::size_t i = 0; i < nf; ++i) {
      glm::dvec3 w0 = zero ? glm::dvec3(0.0) : warm[vertex[i]];
      if (small) {
        const T* bi = d.b + 4 * i;
        const T* m = binv + 12 * i;
        w0 = glm::dvec3(double(m[0] * bi[0] + m[4] * bi[1] + m[8] * bi[2]),
                        double(m[1] * bi[0] + m[5] * bi[1] + m[9] * bi[2]),
                        double(m[2] * bi[0] + m[6] * bi[1] + m[10] * bi[2]));
      }
      d.dv[4 * i] = static_cast<T>(w0.x);
      d.dv[4 * i + 1] = static_cast<T>(w0.y);
      d.dv[4 * i + 2] = static_cast<T>(w0.z);
      d.dv[4 * i + 3] = T(0);
    }
  }
  d.inv = inv;
  if (!st.agg.empty() && st.coarse_h > 0.0) {
    d.nc = st.coarse_count;
    d.agg = st.agg.data();
    if constexpr (std::is_same_v<T, double>) {
      d.chol = st.coarse.data();
    } else {
      d.chol = st.coarse_f.data();
    }
    d.chol_first = st.coarse_first.data();
    d.chol_start = st.coarse_start.data();
    // rc, xc, and a coarse vector for each member after the first.
    const std::size_t members = step_team_ != nullptr ? step_team_->size() : 1;
    const std::size_t size = 4 * d.nc * (members + 1);
    T* cbuf = nullptr;
    if constexpr (std::is_same_v<T, double>) {
      cbuf_d_.assign(size, 0.0);
      cbuf = cbuf_d_.data();
    } else {
      cbuf_f_.assign(size, 0.0f);
      cbuf = cbuf_f_.data();
    }
    d.rc = cbuf;
    d.xc = d.rc + 4 * d.nc;
    d.rc_parts = d.xc + 4 * d.nc;
  }
  double r2 = 0.0;
  const int it = run_cg(d, max_iterations, tol2, r2);
  stats.cg_iterations += it;
  stats.relative_residual = std::sqrt(r2 / std::max(b2, 1e-300));
  return d.dv;
}

double ImplicitEulerState::fixed_energy(System& sys, const SoftBody& body) {
  if (!sys.fixed_energy_valid) {
    const System::SpringSet& sx = sys.fixed;
    sys.fixed_energy = spring_energy(sx.a.data(), sx.b.data(), sx.rest.data(), sx.k.data(),
                                     sx.a.size(), body.positions().data());
    sys.fixed_energy_valid = true;
  }
  return sys.fixed_energy;
}

double ImplicitEulerState::spring_pass(System& sys, const SoftBody& body, double h, bool energy) {
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const double c = body.material().spring_damping_N_s_per_m;
  f_.assign(x.size(), glm::dvec3(0.0));
  // Member t takes a run of the springs into its own force array (member 0 into f_), then the
  // arrays are added in member order, each member a run of vertices.
  const System::SpringSet& sa = sys.active;
  f_parts_.resize(array_members() - 1);
  blocks_.resize(4 * sa.a.size());
  std::array<double, kMaxThreads> partial{};
  run_parts(
      step_team_, sa.a.size(),
      [&](std::size_t first, std::size_t last, unsigned t) {
        glm::dvec3* f = member_array(f_, f_parts_, t);
        const std::size_t real = sa.count > first ? std::min(sa.count, last) - first : 0;
        const std::size_t m = last - first;
        float* blocks = blocks_.data() + 4 * first;
        if (energy) {
          partial[t] = spring_forces_energy(sa.a.data() + first, sa.b.data() + first,
                                            sa.rest.data() + first, sa.k.data() + first, m, real,
                                            x.data(), v.data(), c, h, f, blocks, bound_hessian_);
        } else {
          spring_forces(sa.a.data() + first, sa.b.data() + first, sa.rest.data() + first,
                        sa.k.data() + first, m, real, x.data(), v.data(), c, h, f, blocks,
                        bound_hessian_);
        }
      },
      kChunk);
  add_parts(f_, f_parts_);
  double elastic = 0.0;
  if (energy) {
    for (unsigned t = 0; t < members(); ++t)
      elastic += partial[t];
    elastic += fixed_energy(sys, body);
  }
  // The halo completes the spring forces on the border of the awake region (for waking).
  const System::SpringSet& sb = sys.halo;
  if (sb.count > 0) {
    spring_forces(sb.a.data(), sb.b.data(), sb.rest.data(), sb.k.data(), sb.a.size(), sb.count,
                  x.data(), v.data(), c, h, f_.data(), nullptr, bound_hessian_);
  }
  return elastic;
}

void ImplicitEulerState::add_parts(std::vector<glm::dvec3>& into,
                                   const std::vector<std::vector<glm::dvec3>>& parts) {
  if (parts.empty()) return;  // one thread: `into` has everything
  // Each member a run of vertices; the arrays are added in member order.
  run_parts(step_team_, into.size(), [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t i = first; i < last; ++i) {
      glm::dvec3 s = into[i];
      for (const auto& part : parts)
        s += part[i];
      into[i] = s;
    }
  });
}

double ImplicitEulerState::volume_pass(const SoftBody& body) {
  const auto& x = body.positions();
  const std::uint32_t* idx = body.triangles().indices.data();
  const std::size_t nt = body.triangles().size();
  grad_.assign(x.size(), glm::dvec3(0.0));
  // Member t takes a run of the triangles into its own gradient array (member 0 into grad_).
  const unsigned n = members();
  grad_parts_.resize(array_members() - 1);
  std::array<double, kMaxThreads> partial{};
  run_parts(step_team_, nt, [&](std::size_t first, std::size_t last, unsigned t) {
    partial[t] = volume_gradient(idx, first, last, x.data(), member_array(grad_, grad_parts_, t));
  });
  add_parts(grad_, grad_parts_);
  double six_v = 0.0;
  for (unsigned t = 0; t < n; ++t)
    six_v += partial[t];
  return six_v;
}

double ImplicitEulerState::end_pass(Structure& st, System& sys, const SoftBody& body,
                                    const IntegratorOptions& options) {
  // The passes the next step starts with, at the state it will start from: the guard's spring
  // and volume energies come out of them, and the next step need not take them again.
  Structure::Ahead& ahead = st.ahead;
  ahead.h = options.dt_s;
  ahead.elastic = spring_pass(sys, body, ahead.h, true);
  ahead.six_v = 0.0;
  double elastic = ahead.elastic;
  if (has_volume_term(body)) {
    ahead.six_v = volume_pass(body);
    elastic += volume_term_energy(body, outward_volume(body, ahead.six_v));
  }
  ahead.system = sys.id;
  ahead.members = members();
  f_.swap(ahead.f);
  grad_.swap(ahead.grad);
  blocks_.swap(ahead.blocks);
  return elastic;
}

unsigned ImplicitEulerState::members() const {
  return step_team_ != nullptr ? step_team_->size() : 1;
}

void ImplicitEulerState::checkpoint() const {
  if (step_team_ != nullptr) step_team_->checkpoint();
}

unsigned ImplicitEulerState::array_members() const {
  return step_team_ != nullptr && !step_team_->sequential() ? step_team_->size() : 1;
}

StepThreads* ImplicitEulerState::team(const IntegratorOptions& options) {
  if (team_ && team_->sequential()) return team_.get();  // a far-field solver's, for good
  const unsigned want = std::min(options.threads, kMaxThreads);
  if (want <= 1) return nullptr;
  if (!team_ || team_->size() != want) team_ = std::make_shared<StepThreads>(want);
  return team_.get();
}

void ImplicitEulerState::gather_contacts(const System& sys, const SoftBody& body, double h2,
                                         std::vector<double>* step_residual, const Structure& st) {
  // Contacts: k n n^T blocks on the diagonal, their h^2 H v term on the right-hand side.
  const auto& v = body.velocities();
  const std::size_t n = v.size();
  contacts_.clear();
  for (const SoftBody::ContactTerm& ct : body.contacts()) {
    const std::uint32_t i = ct.vertex;
    if (i >= n || !free_[i] || sys.compact[i] == kNotFree) continue;
    const std::size_t ci = sys.compact[i];
    if (step_residual != nullptr) (*step_residual)[st.full.agg[st.full.compact[i]]] = kNeverQuiet;
    const double kc = h2 * ct.stiffness_N_per_m;
    const glm::dvec3 nn = ct.normal;
    contacts_.insert(contacts_.end(), {double(ci), nn.x, nn.y, nn.z, kc});
    const double nv = kc * glm::dot(nn, v[i]);
    rhs_[4 * ci] -= nv * nn.x;
    rhs_[4 * ci + 1] -= nv * nn.y;
    rhs_[4 * ci + 2] -= nv * nn.z;
  }
}

namespace {

/// A symmetric 3 x 3 block (xx, yy, zz, xy, xz, yz) plus a I + s s^T (s and a as block_rows'
/// floats).
void add_block(double (&m)[6], const float* b) {
  const double sx = b[0], sy = b[1], sz = b[2], a = b[3];
  m[0] += a + sx * sx;
  m[1] += a + sy * sy;
  m[2] += a + sz * sz;
  m[3] += sx * sy;
  m[4] += sx * sz;
  m[5] += sy * sz;
}

/// The inverse of the symmetric block m as three 4-lane rows (pads 0) into out (12); the
/// identity when m is singular (a row without mass or springs).
template <class T>
void invert_block(const double (&m)[6], T* out) {
  const double xx = m[0], yy = m[1], zz = m[2], xy = m[3], xz = m[4], yz = m[5];
  const double c00 = yy * zz - yz * yz, c01 = xz * yz - xy * zz, c02 = xy * yz - xz * yy;
  const double det = xx * c00 + xy * c01 + xz * c02;
  double inv[9] = {1, 0, 0, 0, 1, 0, 0, 0, 1};
  if (det > 0.0 && std::isfinite(det)) {
    const double r = 1.0 / det;
    const double c11 = xx * zz - xz * xz, c12 = xy * xz - xx * yz, c22 = xx * yy - xy * xy;
    const double e[9] = {c00, c01, c02, c01, c11, c12, c02, c12, c22};
    for (std::size_t k = 0; k < 9; ++k)
      inv[k] = e[k] * r;
  }
  for (std::size_t row = 0; row < 3; ++row) {
    for (std::size_t l = 0; l < 3; ++l)
      out[4 * row + l] = static_cast<T>(inv[3 * row + l]);
    out[4 * row + 3] = T(0);
  }
}

}  // namespace

void ImplicitEulerState::block_rows(System& sys) {
  // Each entry's block copied from its spring's (so the products read them in order), the held
  // springs' blocks listed for the diagonal, and per row the inverse of its 3 x 3 diagonal
  // block for block Jacobi: the mass part, its springs' blocks and its contacts' h^2 k n n^T.
  // The surface's soft direction is its normal, which is no axis: the block, not its diagonal,
  // is what holds it apart from the stiff tangent ones.
  const std::size_t nf = sys.vertex.size();
  const std::uint32_t* prow = sys.prow.data();
  const std::size_t entries = nf > 0 ? prow[nf] : 0;
  entry_blocks_.resize(4 * entries);
  diag_blocks_.assign(6 * nf, 0.0);
  jinv_.resize(12 * nf);
  jinv_f_.resize(12 * nf);
  const float* blk = blocks_.data();
  const std::uint32_t* spring = sys.entry_spring.data();
  const double* self = sys.diagonal.self.data();
  float* out = entry_blocks_.data();
  double* diag = diag_blocks_.data();
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t ci = first; ci < last; ++ci) {
      double m[6] = {self[ci], self[ci], self[ci], 0.0, 0.0, 0.0};
      for (std::uint32_t e = prow[ci]; e < prow[ci + 1]; ++e) {
        float* o = out + 4 * std::size_t{e};
        if (spring[e] == kNotFree) {
          o[0] = o[1] = o[2] = o[3] = 0.0f;
          continue;
        }
        std::memcpy(o, blk + 4 * std::size_t{spring[e]}, 4 * sizeof(float));
        add_block(m, o);
      }
      std::copy(std::begin(m), std::end(m), diag + 6 * ci);
    }
  });
  held_blocks_.clear();
  const std::vector<std::uint32_t>& held = sys.held_springs;
  for (std::size_t k = 0; k < held.size(); k += 2) {
    const std::uint32_t ci = held[k];
    const float* b = blk + 4 * std::size_t{held[k + 1]};
    held_blocks_.insert(held_blocks_.end(),
                        {double(ci), double(b[0]), double(b[1]), double(b[2]), double(b[3])});
    double(&m)[6] = *reinterpret_cast<double(*)[6]>(diag + 6 * std::size_t{ci});
    add_block(m, b);
  }
  for (std::size_t c = 0; c < contacts_.size(); c += 5) {
    const std::size_t ci = static_cast<std::size_t>(contacts_[c]);
    const double kc = contacts_[c + 4], nx = contacts_[c + 1], ny = contacts_[c + 2],
                 nz = contacts_[c + 3];
    double* m = diag + 6 * ci;
    m[0] += kc * nx * nx;
    m[1] += kc * ny * ny;
    m[2] += kc * nz * nz;
    m[3] += kc * nx * ny;
    m[4] += kc * nx * nz;
    m[5] += kc * ny * nz;
  }
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t ci = first; ci < last; ++ci) {
      const double(&m)[6] = *reinterpret_cast<const double(*)[6]>(diag + 6 * ci);
      invert_block(m, jinv_.data() + 12 * ci);
      invert_block(m, jinv_f_.data() + 12 * ci);
    }
  });
}

ImplicitEulerState::System& ImplicitEulerState::substep(SoftBody& body, Structure& st,
                                                        const IntegratorOptions& options, double h,
                                                        double fraction, StepStats& stats,
                                                        double* energy_out, bool reuse_ahead) {
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
  checkpoint();
  if (st.asleep > 0) wake_loaded(st, body);
  System* sys = &system(st, body);

  // Springs with a solved end: forces, the h^2 H v term of the right-hand side and their blocks
  // of the solve's matrix (H each spring's clamped Hessian, spring_kernels.h). The others only add
  // their (constant) energy to the start state's. The last step's end_pass took them (and the
  // volume pass) at this state already, if nothing changed since.
  Structure::Ahead& ahead = st.ahead;
  const bool reuse = reuse_ahead && ahead.system == sys->id && ahead.h == h;
  double spring_energy = 0.0;
  if (reuse) {
    f_.swap(ahead.f);
    blocks_.swap(ahead.blocks);
    spring_energy = ahead.elastic;
    stats.reused_end_pass = true;
  } else {
    spring_energy = spring_pass(*sys, body, h, energy_out != nullptr);
  }

  // Volume term (explicit): p dV/dx_i, p = K (V0 - V) / V0. 6 dV/dx_i is the sum over the
  // triangles around i of x_j x x_k; around a closed fan that equals the sum of the triangles'
  // area vectors (x_j - x_i) x (x_k - x_i) (the x_i x (x_k - x_j) terms telescope to zero), the
  // same vector for all three corners: one cross product per triangle instead of three. The
  // volume comes out of the same pass (x_0 . N = x_0 . (x_1 x x_2)). The term applies to closed
  // bodies only, whose fans are closed.
  double p6 = 0.0, volume_energy = 0.0;
  const bool volume_term = has_volume_term(body);
  if (volume_term) {
    double six_v = ahead.six_v;
    if (reuse) {
      grad_.swap(ahead.grad);
    } else {
      six_v = volume_pass(body);
    }
    const double volume = outward_volume(body, six_v);
    // The volume is measured outward whatever the faces' winding; the gradient follows it.
    p6 = pressure_factor(body, volume);
    volume_energy = volume_term_energy(body, volume);
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
  // The bound weights h^2 k + h c per class: the coarse level and the sleep test use them.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h2 * st.k_class[k] + h * c;
  const std::size_t n4 = 4 * nf;
  update_diagonal(*sys, body, h, w);
  const System::Diagonal& dg = sys->diagonal;
  rhs_.resize(n4);
  row_residual_.resize(nf);
  row_gradient_.resize(nf);
  // The rows split over the team: per row its residual force and pressure gradient (squared),
  // summed per aggregate below in row order.
  run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t ci = first; ci < last; ++ci) {
      const std::uint32_t i = vertex[ci];
      const glm::dvec3 f =
          net_force(m[i], g, fext[i], drag, v[i], f_[i], p6, volume_term ? &grad_[i] : nullptr);
      // A loaded vertex does not sleep (the load is applied again step after step).
      row_residual_[ci] = fext[i] != glm::dvec3(0.0) ? kNeverQuiet : glm::dot(f, f);
      row_gradient_[ci] = volume_term ? glm::dot(grad_[i], grad_[i]) : 0.0;
      store_rhs_row(rhs_.data() + 4 * ci, h, f);
    }
  });
  const double weight2 = dg.weight2;
  // Per aggregate, for sleeping: the sums over its vertices of the squared residual force and
  // pressure gradient.
  std::fill(st.step_residual.begin(), st.step_residual.end(), 0.0);
  std::fill(st.step_gradient.begin(), st.step_gradient.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t A = full_agg[full_compact[vertex[ci]]];
    st.step_residual[A] += row_residual_[ci];
    if (volume_term) st.step_gradient[A] += row_gradient_[ci];
  }
  gather_contacts(*sys, body, h2, &st.step_residual, st);
  // The solve starts from the warm start, the last step's dv. It stops at the relative tolerance
  // or when the residual force is below the absolute one (see IntegratorOptions).
  auto& warm = body.warm_start();
  const CgTolerances tol = cg_tolerances(options, h, weight2, nf);
  // float reaches a relative residual of about 1e-6 (its rounding of b and A p): below 1e-5
  // the solve runs in double.
  if (options.cg_coarse_level) {
    update_coarse(*sys, st, body, h);
  } else {
    sys->coarse_h = -1.0;  // keeps solve() on Jacobi alone
  }
  // v += dv (solved vertices only), x += h v (every vertex with mass); the warm start keeps dv.
  // Per aggregate, for sleeping: the sum over its vertices of the squared force that one more
  // step at their speed would add to their residual (the diagonal, inertia and springs, times
  // the speed over h): a vertex stopped while it moves that much was not at rest.
  row_speed_.resize(nf);
  const auto apply = [&](const auto* dvs) {
    run_parts(step_team_, nf, [&](std::size_t first, std::size_t last, unsigned) {
      for (std::size_t ci = first; ci < last; ++ci) {
        const std::uint32_t i = vertex[ci];
        const glm::dvec3 d{double(dvs[4 * ci]), double(dvs[4 * ci + 1]), double(dvs[4 * ci + 2])};
        warm[i] = d;
        v[i] += d;
        const double* block = diag_blocks_.data() + 6 * ci;
        const double stop = (block[0] + block[1] + block[2]) / (3.0 * h);
        row_speed_[ci] = stop * stop * glm::dot(v[i], v[i]);
      }
    });
  };
  if (options.cg_relative_tolerance >= 1e-5) {
    apply(solve<float>(*sys, warm, options.cg_warm_start, options.max_cg_iterations, tol.rel2,
                       tol.abs2, stats));
  } else {
    apply(solve<double>(*sys, warm, options.cg_warm_start, options.max_cg_iterations, tol.rel2,
                        tol.abs2, stats));
  }
  // Vertices outside the solve keep no warm start.
  const std::uint32_t* compact = sys->compact.data();
  run_parts(step_team_, n, [&](std::size_t first, std::size_t last, unsigned) {
    for (std::size_t i = first; i < last; ++i) {
      if (compact[i] == kNotFree) warm[i] = glm::dvec3(0.0);
      if (m[i] > 0.0) x[i] += h * v[i];
    }
  });
  std::fill(st.step_speed.begin(), st.step_speed.end(), 0.0);
  for (std::size_t ci = 0; ci < nf; ++ci)
    st.step_speed[full_agg[full_compact[vertex[ci]]]] += row_speed_[ci];
  return *sys;
}

}  // namespace bisturi::sim
