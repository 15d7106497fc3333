// Sleeping for the implicit integrator (integrator.h, docs/sim/integrator.md "Sleeping"):
// aggregates of the free system at rest are held fixed and leave the solve; the border
// of the awake region, the pressure and the external loads wake them.

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "integrator_shared.h"
#include "integrator_state.h"

namespace bisturi::sim {
namespace {

constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
/// Measured per aggregate as the solver measures the whole body (the root of the sum of squares
/// over its vertices against the tolerance summed the same way): an aggregate sleeps when its
/// residual force and the force that one more step of its motion would add (stopping it) both
/// stayed under the tolerance; what it keeps asleep is then under twice the tolerance, and it
/// wakes when that can exceed three times. The solve's own stop is on the whole body, so at rest
/// it leaves single aggregates at 0.1-2.5 tolerances (docs/sim/integrator.md): a sleeping
/// aggregate keeps a residual of the same order.
constexpr double kSleepResidual2 = 1.0;
constexpr double kSleepSpeed2 = 1.0;
constexpr double kWake2 = 9.0;

}  // namespace

double ImplicitEulerState::tolerance2(const Structure& st, std::uint32_t aggregate,
                                      const IntegratorOptions& options) {
  const glm::dvec3 g = options.gravity_m_s2;
  const double frac = options.cg_weight_fraction, floor = options.cg_force_floor_N;
  const double count = double(st.agg_start[aggregate + 1] - st.agg_start[aggregate]);
  return frac * frac * glm::dot(g, g) * st.agg_mass2[aggregate] + floor * floor * count;
}

void ImplicitEulerState::wake_all(Structure& st) {
  if (st.asleep == 0) return;
  std::fill(st.awake.begin(), st.awake.end(), std::uint8_t{1});
  std::fill(st.quiet.begin(), st.quiet.end(), std::uint16_t{0});
  st.asleep = 0;
  st.part_dirty = true;
}

void ImplicitEulerState::wake_aggregate(Structure& st, std::uint32_t aggregate) {
  if (st.awake[aggregate]) return;
  st.awake[aggregate] = 1;
  st.quiet[aggregate] = 0;
  --st.asleep;
  st.part_dirty = true;
}

void ImplicitEulerState::wake(const SoftBody& body) {
  for (Structure& st : structures_) {
    if (st.generation != body.derived_generation()) continue;
    wake_all(st);
    st.full.fixed_energy_valid = false;
  }
}

bool ImplicitEulerState::sleeps_entirely(const Structure& st, const SoftBody& body) {
  if (st.asleep == 0 || st.asleep != st.awake.size()) return false;
  free_mask(body);
  if (free_ != st.free_mask) return false;
  const auto& fext = body.external_forces();
  for (std::size_t i = 0; i < fext.size(); ++i) {
    if (free_[i] && fext[i] != glm::dvec3(0.0)) return false;
  }
  for (const SoftBody::ContactTerm& ct : body.contacts()) {
    if (ct.vertex < free_.size() && free_[ct.vertex]) return false;
  }
  return true;
}

void ImplicitEulerState::wake_loaded(Structure& st, const SoftBody& body) {
  const System& full = st.full;
  auto wake_vertex = [&](std::uint32_t i) {
    if (i < full.compact.size() && full.compact[i] != kNone) {
      wake_aggregate(st, full.agg[full.compact[i]]);
    }
  };
  for (std::uint32_t i : loaded_)
    wake_vertex(i);
  for (const SoftBody::ContactTerm& ct : body.contacts())
    wake_vertex(ct.vertex);
}

ImplicitEulerState::System& ImplicitEulerState::system(Structure& st, const SoftBody& body) {
  if (st.asleep == 0) return st.full;
  if (!st.part_dirty) return st.part;
  const std::size_t n = st.free_mask.size();
  System& part = st.part;
  build_over_aggregates(st, part, st.awake);
  // The border: sleeping free vertices that share a spring or a triangle with an awake one (the
  // forces and the pressure gradient on them change when it moves).
  std::vector<std::uint8_t> border(n, 0);
  auto mark = [&](std::uint32_t i) {
    if (!mask_[i] && st.free_mask[i]) border[i] = 1;
  };
  const std::vector<Spring>& springs = body.springs();
  for (const Spring& sp : springs) {
    if (mask_[sp.a] != mask_[sp.b]) {
      mark(sp.a);
      mark(sp.b);
    }
  }
  const auto& idx = body.triangles().indices;
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    if (mask_[idx[t]] || mask_[idx[t + 1]] || mask_[idx[t + 2]]) {
      mark(idx[t]);
      mark(idx[t + 1]);
      mark(idx[t + 2]);
    }
  }
  part.border.clear();
  for (std::size_t i = 0; i < n; ++i) {
    if (border[i]) part.border.push_back(static_cast<std::uint32_t>(i));
  }
  // The halo: springs with a border end and no awake one (the awake ones are in part.active).
  System::SpringSet& halo = part.halo;
  halo.a.clear();
  halo.b.clear();
  halo.rest.clear();
  halo.k.clear();
  for (const Spring& sp : springs) {
    const std::uint32_t a = sp.a, b = sp.b;
    if (mask_[a] || mask_[b] || !(border[a] || border[b])) continue;
    halo.a.push_back(a);
    halo.b.push_back(b);
    halo.rest.push_back(sp.rest_m);
    halo.k.push_back(sp.k_N_per_m);
  }
  halo.count = halo.a.size();
  const std::size_t padded = (halo.count + 3) / 4 * 4;  // null springs: vertex 0 to itself
  halo.a.resize(padded, 0);
  halo.b.resize(padded, 0);
  halo.rest.resize(padded, 0.0);
  halo.k.resize(padded, 0.0);
  st.part_dirty = false;
  return part;
}

bool ImplicitEulerState::wake_by_forces(Structure& st, const System& sys, const SoftBody& body,
                                        const IntegratorOptions& options, double p6) {
  const System& full = st.full;
  const auto& m = body.masses();
  const glm::dvec3 g = options.gravity_m_s2;
  const bool volume_term = integrator_detail::has_volume_term(body);
  // The border: its forces are complete (springs to awake vertices in the active set, the others
  // in the halo) and its velocity is zero. Their squared residuals are summed per aggregate into
  // step_residual (the right-hand side's pass refills it after).
  std::fill(st.step_residual.begin(), st.step_residual.end(), 0.0);
  for (std::uint32_t j : sys.border) {
    glm::dvec3 r = f_[j] + m[j] * g;
    if (volume_term) r += p6 * grad_[j];
    st.step_residual[full.agg[full.compact[j]]] += glm::dot(r, r);
  }
  // A sleeping aggregate wakes when its residual can exceed three tolerances: the border
  // vertices' residuals are exact, the others changed only by the pressure since it fell asleep
  // (bounded by the residual and gradient it fell asleep with; the border's share of that
  // bound is counted twice, which errs towards waking).
  bool woke = false;
  for (std::uint32_t a = 0; a < st.awake.size(); ++a) {
    if (st.awake[a]) continue;
    const double bound =
        st.sleep_residual[a] + std::abs(p6 - st.sleep_p6[a]) * st.sleep_gradient[a];
    const double border = st.step_residual[a] / tolerance2(st, a, options);
    if (bound * bound + border > kWake2) {
      wake_aggregate(st, a);
      woke = true;
    }
  }
  return woke;
}

void ImplicitEulerState::update_sleep(Structure& st, SoftBody& body,
                                      const IntegratorOptions& options) {
  auto& v = body.velocities();
  auto& warm = body.warm_start();
  const int steps = std::clamp(options.sleep_steps, 1, 60000);
  for (std::uint32_t a = 0; a < st.awake.size(); ++a) {
    if (!st.awake[a]) continue;
    const double tol2 = tolerance2(st, a, options);
    const bool quiet =
        st.step_residual[a] <= kSleepResidual2 * tol2 && st.step_speed[a] <= kSleepSpeed2 * tol2;
    st.quiet[a] = quiet ? static_cast<std::uint16_t>(std::min(st.quiet[a] + 1, 60000)) : 0;
  }
  for (std::uint32_t a = 0; a < st.awake.size(); ++a) {
    if (!st.awake[a] || st.quiet[a] < steps) continue;
    const double tol2 = tolerance2(st, a, options);
    const double residual2 = st.step_residual[a] / tol2, speed2 = st.step_speed[a] / tol2;
    st.awake[a] = 0;
    st.quiet[a] = 0;
    ++st.asleep;
    st.part_dirty = true;
    st.sleep_p6[a] = p6_;
    st.sleep_residual[a] = std::sqrt(residual2) + std::sqrt(speed2);
    st.sleep_gradient[a] = std::sqrt(st.step_gradient[a] / tol2);
    for (std::uint32_t e = st.agg_start[a]; e < st.agg_start[a + 1]; ++e) {
      const std::uint32_t i = st.full.vertex[st.agg_rows[e]];
      v[i] = glm::dvec3(0.0);
      warm[i] = glm::dvec3(0.0);
    }
  }
}

}  // namespace bisturi::sim
