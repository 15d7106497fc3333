// The multirate step's far field (IntegratorOptions::far_field_interval = N; docs/sim/
// integrator.md, "Multirate stepping"): one single-rate step of N dt over the whole body, run on a
// copy of it in a fiber, a slice of it per step, so that a step costs the near region's solve
// and an N-th of the far one. A period of N steps:
//
//   step 0: the last job has ended (its result is the copy's state, N dt on from where it
//   started, that is now); the near region's neighbours take it at once; the copy takes the
//   near region's state and this step's loads, and the next job starts. Its first act keeps
//   the result aside.
//   steps 1 .. N - 1: a block of aggregates takes the result, and so does any aggregate that
//   joins the near region.
//   every step: the near region is solved with dt against the far vertices held; the job runs
//   until the step's slice of its estimated time is used up (at the period's last step, to its
//   end).
//
// The job's result does not depend on where its slices end (it runs the same code on the same
// data whatever the clock says), so runs stay bit-identical. The copy's solver has a sequential
// team of kFarParts parts: its passes and products are cut into parts, after each of which the
// fiber may suspend.

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <limits>
#include <memory>
#include <utility>

#include "fiber.h"
#include "integrator_shared.h"
#include "integrator_state.h"
#include "step_threads.h"

namespace bisturi::sim {

using namespace integrator_detail;  // NOLINT(google-build-using-namespace)

namespace {

using Clock = std::chrono::steady_clock;

/// Parts of the far solver's passes: about 60 us each at 20k vertices (a part is as long as a
/// slice can overrun its end).
constexpr unsigned kFarParts = 16;
/// The least a slice runs (a job with no estimate yet runs this much per step).
constexpr double kMinSliceS = 30e-6;

/// A length of time in seconds as the clock's duration.
Clock::duration seconds(double s) {
  return std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(s));
}

/// The far field's solver options: the caller's, single-rate, for a step of N dt.
IntegratorOptions far_options(const IntegratorOptions& options) {
  IntegratorOptions far = options;
  far.far_field_interval = 1;
  far.sleeping = false;  // the copy's state is rewritten every period
  far.dt_s = options.dt_s * double(options.far_field_interval);
  return far;
}

}  // namespace

struct ImplicitEulerState::FarField {
  explicit FarField(const SoftBody& original) : body(original) {}
  /// A job part-way is run to its end while the members it uses are alive.
  ~FarField() {
    deadline = Clock::time_point::max();
    try {
      while (fiber.part_way())
        fiber.resume();
    } catch (...) {  // NOLINT(bugprone-empty-catch): a destructor has nobody to tell
    }
  }
  FarField(const FarField&) = delete;
  FarField& operator=(const FarField&) = delete;
  /// In the job: back to the step when the slice is used up (elsewhere, nothing).
  void suspend_when_due() const {
    if (Fiber::current() == &fiber && Clock::now() >= deadline) Fiber::suspend();
  }

  SoftBody body;  ///< the copy the job advances
  ImplicitEulerState solver;
  Fiber fiber;
  IntegratorOptions options;  ///< the caller's, single-rate, with dt_s = N dt
  int interval = 1;           ///< N
  /// The main body's derived generation and constraint edits the copy was made for.
  std::uint64_t generation = 0, constraints = 0;
  /// The job: its events and stats, whether it has ended with a result not yet applied.
  std::vector<SimEvent> events;
  StepStats stats;
  bool result = false;
  /// The last result, kept aside by the job that followed it (its first act) for the steps
  /// that apply it, and per aggregate of the full system whether it still has to.
  std::vector<glm::dvec3> pending_x, pending_v;
  std::vector<std::uint8_t> agg_pending;
  /// Scheduling: the current slice's end, the job's time so far, the last whole job's time.
  Clock::time_point deadline = Clock::time_point::max();
  double job_s = 0.0, estimate_s = 0.0;
};

void ImplicitEulerState::far_reset(Structure& st, const SoftBody& body,
                                   const IntegratorOptions& options) {
  auto ff = std::make_shared<FarField>(body);
  ff->generation = body.derived_generation();
  ff->constraints = body.constraint_edits();
  ff->options = far_options(options);
  ff->interval = options.far_field_interval;
  ff->body.clear_forces();
  FarField* raw = ff.get();
  ff->solver.team_ = std::make_shared<StepThreads>(kFarParts, [raw] { raw->suspend_when_due(); });
  ff->solver.prepare(ff->body, ff->options);
  if (st.multirate.far) ff->estimate_s = st.multirate.far->estimate_s;
  st.multirate.far = std::move(ff);  // a job part-way in the old one is run to its end
}

bool ImplicitEulerState::far_follow(Structure& st, const SoftBody& body,
                                    const IntegratorOptions& options, bool untouched) {
  FarField* ff = st.multirate.far.get();
  if (ff == nullptr || ff->generation != body.derived_generation() ||
      ff->constraints != body.constraint_edits()) {
    far_reset(st, body, options);
    return true;
  }
  // Other options (a session lengthens dt when it falls behind): the copy's solver takes them
  // from a new period on (its coarse level follows the step length by itself).
  const IntegratorOptions wanted = far_options(options);
  // A copy that froze is made to follow again once its result has frozen the body (far_finish).
  if (!untouched || (ff->body.frozen() && !ff->result) || !(wanted == ff->options) ||
      ff->interval != options.far_field_interval) {
    far_sync(*ff, body);
    ff->options = wanted;
    ff->interval = options.far_field_interval;
    return true;
  }
  return false;
}

void ImplicitEulerState::far_sync(FarField& ff, const SoftBody& body) {
  finish_far_job(ff);
  ff.result = false;
  ff.events.clear();
  std::fill(ff.agg_pending.begin(), ff.agg_pending.end(), std::uint8_t{0});
  ff.body.positions() = body.positions();
  ff.body.velocities() = body.velocities();
  ff.body.unfreeze();
  ff.solver.wake(ff.body);
}

void ImplicitEulerState::finish_far_job(FarField& ff) {
  ff.deadline = Clock::time_point::max();
  const Clock::time_point t0 = Clock::now();
  if (ff.fiber.part_way()) ff.fiber.resume();
  ff.job_s += std::chrono::duration<double>(Clock::now() - t0).count();
}

bool ImplicitEulerState::far_finish(Structure& st, SoftBody& body, StepStats& stats,
                                    std::vector<SimEvent>& events, std::uint32_t body_index,
                                    std::uint64_t step_index) {
  const Structure::Multirate& mr = st.multirate;
  FarField& ff = *mr.far;
  finish_far_job(ff);
  if (!ff.result) return true;
  ff.result = false;
  for (SimEvent e : ff.events) {
    e.body = body_index;
    e.step = step_index;
    e.reason = "far field: " + e.reason;
    events.push_back(std::move(e));
  }
  ff.events.clear();
  stats.rolled_back = stats.rolled_back || ff.stats.rolled_back;
  stats.cg_iterations += ff.stats.cg_iterations;
  stats.substeps = std::max(stats.substeps, ff.stats.substeps);
  if (ff.stats.frozen || ff.body.frozen()) {
    body.freeze();
    stats.frozen = true;
    return false;
  }
  // The far aggregates take the result in the coming period; the near ones keep their state.
  ff.agg_pending.resize(mr.near.size());
  for (std::size_t a = 0; a < mr.near.size(); ++a)
    ff.agg_pending[a] = mr.near[a] ? 0 : 1;
  return true;
}

std::uint32_t ImplicitEulerState::far_apply_aggregate(Structure& st, SoftBody& body,
                                                      std::uint32_t a, bool from_copy) {
  Structure::Multirate& mr = st.multirate;
  FarField& ff = *mr.far;
  ff.agg_pending[a] = 0;
  const auto& px = from_copy ? ff.body.positions() : ff.pending_x;
  const auto& pv = from_copy ? ff.body.velocities() : ff.pending_v;
  auto& x = body.positions();
  auto& v = body.velocities();
  for (std::uint32_t e = st.agg_start[a]; e < st.agg_start[a + 1]; ++e) {
    const std::uint32_t i = st.full.vertex[st.agg_rows[e]];
    x[i] = px[i];
    v[i] = pv[i];
  }
  MultirateGroups& groups = mr.groups;
  mr.group_marked.resize(groups.six_v.size(), 0);
  for (std::uint32_t k = mr.tri_start[a]; k < mr.tri_start[a + 1]; ++k) {
    const std::uint32_t t = mr.tris[k];
    mr.moved_tris.push_back(t);
    const std::uint32_t g = groups.tri_group[t];
    if (mr.group_marked[g]) continue;
    mr.group_marked[g] = 1;
    mr.moved_groups.push_back(g);
  }
  return st.agg_start[a + 1] - st.agg_start[a];
}

std::uint32_t ImplicitEulerState::far_apply(Structure& st, SoftBody& body, std::size_t phase,
                                            std::size_t interval) {
  Structure::Multirate& mr = st.multirate;
  FarField& ff = *mr.far;
  if (ff.agg_pending.empty()) return 0;
  mr.moved_tris.clear();
  mr.moved_groups.clear();
  std::uint32_t moved = 0;
  const std::size_t nc = ff.agg_pending.size();
  // This phase's block: phases 1 .. N - 1 take runs of aggregates in turn. At a period's start
  // the job has not kept the result aside yet: it is still the copy's state.
  std::size_t first = 0, last = 0;
  if (phase > 0) {
    first = nc * (phase - 1) / (interval - 1);
    last = nc * phase / (interval - 1);
  }
  for (std::size_t k = first; k < last; ++k) {
    const std::uint32_t a = mr.block_order[k];
    if (ff.agg_pending[a]) moved += far_apply_aggregate(st, body, a, false);
  }
  for (std::size_t a = 0; a < nc; ++a) {
    // One that joined the near region takes it before its first near solve.
    if (ff.agg_pending[a] && mr.near[a])
      moved += far_apply_aggregate(st, body, static_cast<std::uint32_t>(a), phase == 0);
  }
  if (phase == 0) {
    // The near region's neighbours at once: its solves hold them, and the next job pairs its
    // state with theirs.
    for (std::size_t a = 0; a < nc; ++a) {
      if (!mr.near[a]) continue;
      for (std::uint32_t e = mr.adj_start[a]; e < mr.adj_start[a + 1]; ++e) {
        if (ff.agg_pending[mr.adj[e]]) moved += far_apply_aggregate(st, body, mr.adj[e], true);
      }
    }
  }
  if (!mr.moved_tris.empty()) {
    // A triangle listed by two aggregates is summed twice: the same value.
    mr.groups.update(mr.moved_tris, mr.moved_groups, body.triangles().indices, body.positions());
    for (const std::uint32_t g : mr.moved_groups)
      mr.group_marked[g] = 0;
  }
  return moved;
}

void ImplicitEulerState::far_start(Structure& st, const SoftBody& body, std::uint64_t step_index) {
  const Structure::Multirate& mr = st.multirate;
  FarField& ff = *mr.far;
  // The copy takes the near region's state (its far vertices hold the result just applied) and
  // this step's loads, which stand for the period's.
  auto& fx = ff.body.positions();
  auto& fv = ff.body.velocities();
  const auto& x = body.positions();
  const auto& v = body.velocities();
  const std::vector<std::uint32_t>& rows = st.full.vertex;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if (!mr.near[st.full.agg[r]]) continue;
    const std::uint32_t i = rows[r];
    fx[i] = x[i];
    fv[i] = v[i];
  }
  ff.body.set_loads_from(body);
  ff.job_s = 0.0;
  ff.fiber.start([&ff, step_index] {
    // The last result aside first: the coming steps apply it while this job moves the copy.
    // Whole, before any chance to suspend: the next step applies from it.
    ff.pending_x = std::as_const(ff.body).positions();
    ff.pending_v = std::as_const(ff.body).velocities();
    ff.stats = ff.solver.step(ff.body, ff.options, ff.events, 0, step_index);
    ff.result = true;
  });
}

void ImplicitEulerState::far_slice(FarField& ff, std::size_t phase, std::size_t interval,
                                   Clock::time_point step_start, double budget_s) {
  if (!ff.fiber.part_way()) return;
  if (phase + 1 >= interval) {
    finish_far_job(ff);
  } else {
    // An even share of what the estimate leaves, over the steps left in the period but the
    // last quarter, which is kept for a job that takes longer than the last one did (more CG
    // iterations, a retry) instead of running it all at the period's last step.
    const double left = std::max(ff.estimate_s - ff.job_s, 0.0);
    const std::size_t spare = interval / 4;
    const std::size_t steps = interval - phase > spare + 1 ? interval - phase - spare : 1;
    const double slice = std::max(kMinSliceS, left / double(steps));
    const Clock::time_point t0 = Clock::now();
    ff.deadline = std::max(t0 + seconds(slice), step_start + seconds(budget_s));
    ff.fiber.resume();
    ff.job_s += std::chrono::duration<double>(Clock::now() - t0).count();
  }
  if (!ff.fiber.part_way()) ff.estimate_s = ff.job_s;
}

}  // namespace bisturi::sim
