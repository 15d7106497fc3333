// Multirate stepping for the implicit integrator (IntegratorOptions::far_field_interval,
// docs/sim/integrator.md "Multirate stepping"): every step solves the near region (the aggregates
// around the loads) with dt, holding the rest, and runs a slice of the far field's job
// (integrator_far_field.cpp). The near solve is the single-rate substep restricted to a region:
// its springs, the triangles around its rows, its rows' check; the volume is kept as a sum of
// groups of triangles, of which a solve recomputes those it moved.

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <utility>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "cg_solver.h"
#include "integrator_shared.h"
#include "integrator_state.h"
#include "morton.h"
#include "spring_kernels.h"
#include "volume_kernels.h"

namespace bisturi::sim {

// The helpers the integrator's files share (integrator_shared.h).
using namespace integrator_detail;  // NOLINT(google-build-using-namespace)

double ImplicitEulerState::MultirateGroups::total() const {
  double sum = 0.0;
  for (const double g : six_v)
    sum += g;
  return sum;
}

void ImplicitEulerState::MultirateGroups::update(const std::vector<std::uint32_t>& triangles,
                                                 const std::vector<std::uint32_t>& groups_to_sum,
                                                 const std::vector<std::uint32_t>& indices,
                                                 const std::vector<glm::dvec3>& x) {
  six_volumes_of(indices.data(), triangles.data(), triangles.size(), x.data(), tri_six_v.data());
  for (const std::uint32_t g : groups_to_sum) {
    double sum = 0.0;
    for (std::uint32_t k = start[g]; k < start[g + 1]; ++k)
      sum += tri_six_v[tris[k]];
    six_v[g] = sum;
  }
}

void ImplicitEulerState::MultirateGroups::update_all(const std::vector<std::uint32_t>& indices,
                                                     const std::vector<glm::dvec3>& x) {
  std::vector<std::uint32_t> all_groups(six_v.size());
  for (std::size_t g = 0; g < all_groups.size(); ++g)
    all_groups[g] = static_cast<std::uint32_t>(g);
  update(tris, all_groups, indices, x);
}

void ImplicitEulerState::make_multirate(Structure& st, const SoftBody& body) {
  Structure::Multirate& mr = st.multirate;
  const System& full = st.full;
  const std::size_t nc = full.coarse_count;
  mr.system = full.id;
  mr.tick = 0;
  mr.period_start = 0;
  mr.near.assign(nc, 0);
  mr.want.assign(nc, 0);
  mr.loaded_tick.assign(nc, 0);
  // The aggregates' neighbours: the aggregates of their rows' neighbours.
  const std::uint32_t* row = full.prow.data();
  const std::uint32_t* col = full.pcol.data();
  std::vector<std::uint32_t> seen(nc, kNotFree);
  mr.adj_start.assign(nc + 1, 0);
  mr.adj.clear();
  for (std::uint32_t a = 0; a < nc; ++a) {
    seen[a] = a;
    for (std::uint32_t e = st.agg_start[a]; e < st.agg_start[a + 1]; ++e) {
      const std::uint32_t r = st.agg_rows[e];
      for (std::uint32_t k = row[r]; k < row[r + 1]; ++k) {
        const std::uint32_t b = full.agg[col[k] & kIndexMask];
        if (seen[b] == a) continue;
        seen[b] = a;
        mr.adj.push_back(b);
      }
    }
    mr.adj_start[a + 1] = static_cast<std::uint32_t>(mr.adj.size());
  }
  // The far field's result is applied in blocks of aggregates taken in the Morton order of
  // their centres, so that a block is a compact piece of the surface and the BVH refits few of
  // its patches for it (the aggregates' own numbering follows the vertices', a mesher's order).
  {
    const auto& x = body.positions();
    std::vector<glm::dvec3> centre(nc, glm::dvec3(0.0));
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (std::size_t r = 0; r < full.vertex.size(); ++r) {
      const glm::dvec3& p = x[full.vertex[r]];
      centre[full.agg[r]] += p;
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    std::vector<std::pair<std::uint32_t, std::uint32_t>> coded(nc);
    const glm::dvec3 scale = 1023.0 / glm::max(hi - lo, glm::dvec3(1e-12));
    for (std::uint32_t a = 0; a < nc; ++a) {
      const double count = double(st.agg_start[a + 1] - st.agg_start[a]);
      const glm::dvec3 q = (centre[a] / std::max(count, 1.0) - lo) * scale;
      coded[a] = {morton_code(q), a};
    }
    std::sort(coded.begin(), coded.end());
    mr.block_order.resize(nc);
    for (std::size_t k = 0; k < nc; ++k)
      mr.block_order[k] = coded[k].second;
  }
  // The triangles with a free corner in each aggregate (listed once per aggregate).
  const auto& tri_idx = body.triangles().indices;
  const std::size_t ntri = tri_idx.size() / 3;
  mr.tri_start.assign(nc + 1, 0);
  auto corner_aggregates = [&](std::size_t t, std::uint32_t(&out)[3]) {
    std::size_t k = 0;
    for (std::size_t c = 0; c < 3; ++c) {
      const std::uint32_t ci = full.compact[tri_idx[3 * t + c]];
      if (ci == kNotFree) continue;
      const std::uint32_t a = full.agg[ci];
      if (std::find(out, out + k, a) == out + k) out[k++] = a;
    }
    return k;
  };
  for (std::size_t t = 0; t < ntri; ++t) {
    std::uint32_t aggs[3];
    const std::size_t k = corner_aggregates(t, aggs);
    for (std::size_t j = 0; j < k; ++j)
      ++mr.tri_start[aggs[j] + 1];
  }
  for (std::size_t a = 0; a < nc; ++a)
    mr.tri_start[a + 1] += mr.tri_start[a];
  mr.tris.resize(mr.tri_start[nc]);
  {
    std::vector<std::uint32_t> at(mr.tri_start.begin(), mr.tri_start.end() - 1);
    for (std::size_t t = 0; t < ntri; ++t) {
      std::uint32_t aggs[3];
      const std::size_t k = corner_aggregates(t, aggs);
      for (std::size_t j = 0; j < k; ++j)
        mr.tris[at[aggs[j]]++] = static_cast<std::uint32_t>(t);
    }
  }
  // Volume groups: a triangle belongs to the aggregate of its first free corner, or to the last
  // group when it has none.
  const auto& idx = body.triangles().indices;
  const std::size_t nt = idx.size() / 3;
  MultirateGroups& groups = mr.groups;
  groups.tri_group.resize(nt);
  groups.start.assign(nc + 2, 0);
  for (std::size_t t = 0; t < nt; ++t) {
    auto group = static_cast<std::uint32_t>(nc);
    for (std::size_t c = 0; c < 3; ++c) {
      const std::uint32_t ci = full.compact[idx[3 * t + c]];
      if (ci != kNotFree) {
        group = full.agg[ci];
        break;
      }
    }
    groups.tri_group[t] = group;
    ++groups.start[group + 1];
  }
  for (std::size_t g = 0; g <= nc; ++g)
    groups.start[g + 1] += groups.start[g];
  groups.tris.resize(nt);
  std::vector<std::uint32_t> fill(groups.start.begin(), groups.start.end() - 1);
  for (std::size_t t = 0; t < nt; ++t)
    groups.tris[fill[groups.tri_group[t]]++] = static_cast<std::uint32_t>(t);
  groups.six_v.assign(nc + 1, 0.0);
  groups.tri_six_v.assign(nt, 0.0);
  groups.valid = false;
  mr.near_region.dirty = true;
}

void ImplicitEulerState::update_near(Structure& st, const SoftBody& body,
                                     const IntegratorOptions& options) {
  Structure::Multirate& mr = st.multirate;
  const System& full = st.full;
  std::fill(mr.want.begin(), mr.want.end(), std::uint8_t{0});
  mr.ring.clear();
  auto seed = [&](std::uint32_t i) {
    if (i >= full.compact.size() || full.compact[i] == kNotFree) return;
    const std::uint32_t a = full.agg[full.compact[i]];
    if (mr.want[a]) return;
    mr.want[a] = 1;
    mr.ring.push_back(a);
  };
  for (const std::uint32_t i : body.loaded_vertices())
    seed(i);
  for (int r = 0; r < options.near_rings; ++r) {
    mr.next_ring.clear();
    for (const std::uint32_t a : mr.ring) {
      for (std::uint32_t e = mr.adj_start[a]; e < mr.adj_start[a + 1]; ++e) {
        const std::uint32_t b = mr.adj[e];
        if (mr.want[b]) continue;
        mr.want[b] = 1;
        mr.next_ring.push_back(b);
      }
    }
    mr.ring.swap(mr.next_ring);
  }
  // Wanted aggregates join at once (with the state the far field last gave them).
  for (std::size_t a = 0; a < mr.want.size(); ++a) {
    if (!mr.want[a]) continue;
    mr.loaded_tick[a] = mr.tick;
    if (mr.near[a]) continue;
    mr.near[a] = 1;
    mr.near_region.dirty = true;
  }
}

void ImplicitEulerState::build_region(Structure& st, const SoftBody& body,
                                      Structure::Region& region,
                                      const std::vector<std::uint8_t>& flags) {
  const std::size_t n = st.free_mask.size();
  System& sys = region.sys;
  build_over_aggregates(st, sys, flags);
  // What its passes visit: the triangles with a corner among the rows, the vertices the spring
  // and triangle passes write, and the volume groups of those triangles.
  const auto& idx = body.triangles().indices;
  region.tris.clear();
  for (std::size_t t = 0; 3 * t + 2 < idx.size(); ++t) {
    if (mask_[idx[3 * t]] | mask_[idx[3 * t + 1]] | mask_[idx[3 * t + 2]])
      region.tris.push_back(static_cast<std::uint32_t>(t));
  }
  std::vector<std::uint8_t> seen(n, 0);
  region.touched.clear();
  auto touch = [&](std::uint32_t i) {
    if (seen[i]) return;
    seen[i] = 1;
    region.touched.push_back(i);
  };
  for (const std::uint32_t i : sys.vertex)
    touch(i);
  for (std::size_t s = 0; s < sys.active.count; ++s) {
    touch(sys.active.a[s]);
    touch(sys.active.b[s]);
  }
  MultirateGroups& groups = st.multirate.groups;
  std::vector<std::uint8_t> group_seen(groups.six_v.size(), 0);
  region.groups.clear();
  for (const std::uint32_t t : region.tris) {
    for (std::size_t c = 0; c < 3; ++c)
      touch(idx[3 * std::size_t{t} + c]);
    const std::uint32_t g = groups.tri_group[t];
    if (!group_seen[g]) {
      group_seen[g] = 1;
      region.groups.push_back(g);
    }
  }
  region.dirty = false;
}

double ImplicitEulerState::region_elastic(const Structure& st, const Structure::Region& region,
                                          const SoftBody& body) const {
  const System::SpringSet& sa = region.sys.active;
  double elastic = spring_energy(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(), sa.a.size(),
                                 body.positions().data());
  if (has_volume_term(body))
    elastic += volume_term_energy(body, outward_volume(body, st.multirate.groups.total()));
  return elastic;
}

void ImplicitEulerState::region_substep(SoftBody& body, Structure& st, Structure::Region& region,
                                        const IntegratorOptions& options, double h,
                                        StepStats& stats, double* energy_out) {
  System& sys = region.sys;
  MultirateGroups& groups = st.multirate.groups;
  auto& x = body.positions();
  auto& v = body.velocities();
  auto& warm = body.warm_start();
  const auto& m = body.masses();
  const auto& fext = body.external_forces();
  const auto& idx = body.triangles().indices;
  const Material& mat = body.material();
  const std::size_t n = x.size();
  const double c = mat.spring_damping_N_s_per_m;
  const glm::dvec3 g = options.gravity_m_s2;
  const std::uint32_t* vertex = sys.vertex.data();
  const std::size_t nf = sys.vertex.size();

  // The region's springs (those with a solved end): forces into f_, cleared where they land.
  // The held vertices stand still during the solve: the springs see them at rest (their own
  // velocities are kept for their next turn), as anchors.
  f_.resize(n);
  for (const std::uint32_t i : region.touched)
    f_[i] = glm::dvec3(0.0);
  held_v_.resize(n, glm::dvec3(0.0));  // zero but on the rows, during the pass below
  for (std::size_t ci = 0; ci < nf; ++ci)
    held_v_[vertex[ci]] = v[vertex[ci]];
  const System::SpringSet& sa = sys.active;
  double elastic = 0.0;
  blocks_.resize(4 * sa.a.size());
  if (energy_out != nullptr) {
    elastic = spring_forces_energy(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(),
                                   sa.a.size(), sa.count, x.data(), held_v_.data(), c, h, f_.data(),
                                   blocks_.data(), bound_hessian_);
  } else {
    spring_forces(sa.a.data(), sa.b.data(), sa.rest.data(), sa.k.data(), sa.a.size(), sa.count,
                  x.data(), held_v_.data(), c, h, f_.data(), blocks_.data(), bound_hessian_);
  }
  for (std::size_t ci = 0; ci < nf; ++ci)
    held_v_[vertex[ci]] = glm::dvec3(0.0);
  // The volume term (explicit): the gradient from the triangles around the rows, the volume
  // from the groups.
  double p6 = 0.0, volume_energy = 0.0;
  const bool volume_term = has_volume_term(body);
  if (volume_term) {
    grad_.resize(n);
    for (const std::uint32_t i : region.touched)
      grad_[i] = glm::dvec3(0.0);
    volume_gradient_of(idx.data(), region.tris.data(), region.tris.size(), x.data(), grad_.data());
    const double volume = outward_volume(body, groups.total());
    p6 = pressure_factor(body, volume);
    volume_energy = volume_term_energy(body, volume);
  }
  if (energy_out != nullptr) {
    double kinetic = 0.0, potential = 0.0;
    for (std::size_t ci = 0; ci < nf; ++ci) {
      const std::uint32_t i = vertex[ci];
      kinetic += 0.5 * m[i] * glm::dot(v[i], v[i]);
      potential -= m[i] * glm::dot(g, x[i]);
    }
    *energy_out = kinetic + potential + elastic + volume_energy;
  }
  // The right-hand side over the rows (as substep()), the contacts on them, and the solve.
  double w[4];
  for (int k = 0; k < 4; ++k)
    w[k] = h * h * st.k_class[k] + h * c;
  update_diagonal(sys, body, h, w);
  rhs_.resize(4 * nf);
  const double drag = mat.drag_per_s;
  for (std::size_t ci = 0; ci < nf; ++ci) {
    const std::uint32_t i = vertex[ci];
    store_rhs_row(
        rhs_.data() + 4 * ci, h,
        net_force(m[i], g, fext[i], drag, v[i], f_[i], p6, volume_term ? &grad_[i] : nullptr));
  }
  gather_contacts(sys, body, h * h, nullptr, st);
  if (options.cg_coarse_level) {
    update_coarse(sys, st, body, h);
  } else {
    sys.coarse_h = -1.0;
  }
  const CgTolerances tol = cg_tolerances(options, h, sys.diagonal.weight2, nf);
  // v += dv, x += h v over the rows; the held vertices keep their state.
  const auto apply = [&](const auto* dvs) {
    for (std::size_t ci = 0; ci < nf; ++ci) {
      const std::uint32_t i = vertex[ci];
      const glm::dvec3 d{double(dvs[4 * ci]), double(dvs[4 * ci + 1]), double(dvs[4 * ci + 2])};
      warm[i] = d;
      v[i] += d;
      x[i] += h * v[i];
    }
  };
  if (options.cg_relative_tolerance >= 1e-5) {
    apply(solve<float>(sys, warm, options.cg_warm_start, options.max_cg_iterations, tol.rel2,
                       tol.abs2, stats));
  } else {
    apply(solve<double>(sys, warm, options.cg_warm_start, options.max_cg_iterations, tol.rel2,
                        tol.abs2, stats));
  }
  groups.update(region.tris, region.groups, idx, x);
}

bool ImplicitEulerState::solve_region(SoftBody& body, Structure& st, Structure::Region& region,
                                      const IntegratorOptions& options, double h, StepStats& stats,
                                      std::vector<SimEvent>& events, std::uint32_t body_index,
                                      std::uint64_t step_index) {
  const std::vector<std::uint32_t>& rows = region.sys.vertex;
  auto& x = body.positions();
  auto& v = body.velocities();
  auto& warm = body.warm_start();
  // The rows' state, for a rollback (the held vertices do not change).
  saved_x_.resize(x.size());
  saved_v_.resize(x.size());
  for (const std::uint32_t i : rows) {
    saved_x_[i] = x[i];
    saved_v_[i] = v[i];
  }
  double energy_before = 0.0;
  for (int attempt = 0; attempt <= options.max_retry_halvings; ++attempt) {
    const int substeps = 1 << attempt;
    StepStats trial;
    for (int s = 0; s < substeps; ++s) {
      region_substep(body, st, region, options, h / substeps, trial,
                     attempt == 0 && s == 0 ? &energy_before : nullptr);
    }
    const std::string reason =
        check(body, options, energy_before, true, region_elastic(st, region, body), &rows);
    if (reason.empty()) {
      stats.substeps = std::max(stats.substeps, substeps);
      stats.cg_iterations += trial.cg_iterations;
      stats.relative_residual = trial.relative_residual;
      stats.rolled_back = stats.rolled_back || attempt > 0;
      stats.awake_vertices += static_cast<std::uint32_t>(rows.size());
      return true;
    }
    events.push_back({SimEventKind::RolledBack, body_index, step_index, substeps, reason});
    for (const std::uint32_t i : rows) {
      x[i] = saved_x_[i];
      v[i] = saved_v_[i];
      warm[i] = glm::dvec3(0.0);
    }
    st.multirate.groups.update(region.tris, region.groups, body.triangles().indices, x);
  }
  events.push_back({SimEventKind::Frozen, body_index, step_index, 1 << options.max_retry_halvings,
                    "still diverging with the smallest substep: the solid is frozen"});
  body.freeze();
  stats.frozen = true;
  stats.rolled_back = true;
  return false;
}

std::optional<StepStats> ImplicitEulerState::step_multirate(SoftBody& body, Structure& st,
                                                            const IntegratorOptions& options,
                                                            std::vector<SimEvent>& events,
                                                            std::uint32_t body_index,
                                                            std::uint64_t step_index) {
  Structure::Multirate& mr = st.multirate;
  const auto step_start = std::chrono::steady_clock::now();
  // Kinematic vertices (a grasp) move their neighbours every step: single-rate steps then, and
  // the far field starts again from the state they leave.
  if (body.kinematic_count() > 0) {
    mr.far_stale = true;
    return std::nullopt;
  }
  // Read before the non-const views below count as edits.
  const bool untouched = mr.state_edits == body.state_edits() && !mr.far_stale;
  StepStats stats;
  step_team_ = nullptr;  // the near region is small: no team
  st.ahead.valid = false;
  wake_all(st);
  // Constraints (anchored and massless vertices stand still), again only when they or the
  // state were edited since the last step.
  const std::uint64_t constraints = body.constraint_edits();
  const std::uint64_t generation = body.derived_generation();
  if (!untouched || constraints != mr.constraint_edits || generation != mr.constraint_generation ||
      st.free_mask.empty()) {
    free_mask(body);  // kinematic vertices are none here
    auto& v = body.velocities();
    for (std::size_t i = 0; i < free_.size(); ++i) {
      if (!free_[i]) v[i] = glm::dvec3(0.0);
    }
    update_free_rows(st, free_, body.masses());
    mr.constraint_edits = constraints;
    mr.constraint_generation = generation;
  }
  const auto interval = static_cast<std::uint64_t>(options.far_field_interval);
  if (mr.system != st.full.id) make_multirate(st, body);
  // The far field's copy: made again for another topology or set of constraints, its state
  // rewritten when the body was edited from outside; a new period starts either way.
  if (far_follow(st, body, options, untouched)) mr.period_start = mr.tick;
  // The groups' sums hold while only this mode's solves move the body.
  if (!mr.groups.valid || !untouched) {
    mr.groups.update_all(body.triangles().indices, body.positions());
    mr.groups.valid = true;
  }
  const std::uint64_t phase = (mr.tick - mr.period_start) % interval;
  // At a period's start, the job that ends it (its result is applied over the period).
  bool alive = phase != 0 || far_finish(st, body, stats, events, body_index, step_index);
  update_near(st, body, options);
  if (alive) stats.awake_vertices += far_apply(st, body, phase, interval);
  if (alive && phase == 0) {
    far_start(st, body, step_index);
    // Near aggregates without a load for the linger time leave the region: the job just
    // started has their state, and solves them from now on.
    for (std::size_t a = 0; a < mr.near.size(); ++a) {
      if (!mr.near[a] || mr.want[a]) continue;
      if (mr.tick - mr.loaded_tick[a] < std::uint64_t(std::max(options.near_linger_steps, 0)))
        continue;
      mr.near[a] = 0;
      mr.near_region.dirty = true;
    }
  }
  // The near region, every step.
  if (alive && std::find(mr.near.begin(), mr.near.end(), std::uint8_t{1}) != mr.near.end()) {
    if (mr.near_region.dirty) build_region(st, body, mr.near_region, mr.near);
    if (!mr.near_region.sys.vertex.empty()) {
      alive = solve_region(body, st, mr.near_region, options, options.dt_s, stats, events,
                           body_index, step_index);
    }
  }
  // A slice of the far field's job.
  if (alive) far_slice(*mr.far, phase, interval, step_start, options.far_step_budget_s);
  ++mr.tick;
  body.clear_forces();
  stats.free_vertices = static_cast<std::uint32_t>(st.full.vertex.size());
  mr.state_edits = body.state_edits();
  mr.far_stale = !alive;
  return stats;
}

}  // namespace bisturi::sim
