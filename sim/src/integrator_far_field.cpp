// The multirate step's far field (IntegratorOptions::far_field_interval = N; docs/sim/
// integrator.md, "Eleventh pass"): one single-rate step of N dt over the whole body, run on a
// copy of it in a fiber, a slice of it per step, so that a step costs the near region's solve
// and an N-th of the far one. A period of N steps:
//
//   step 0 of a period: the last period's result (the copy's state, N dt later than the state it
//   started from, that is now) is written to the body's far vertices - those outside the near
//   region; the copy takes the near region's state and this step's loads; its next job starts.
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

#include "bisturi/sim/integrator.h"
#include "fiber.h"
#include "integrator_shared.h"
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

}  // namespace

struct ImplicitIntegrator::FarField {
  explicit FarField(const SoftBody& original) : body(original) {}

  SoftBody body;  ///< the copy the job advances
  ImplicitIntegrator solver;
  Fiber fiber;
  IntegratorOptions options;  ///< the caller's, single-rate, with dt_s = N dt
  /// The main body's derived generation and constraint edits the copy was made for.
  std::uint64_t generation = 0, constraints = 0;
  /// The job: its events and stats, whether it has ended with a result not yet applied.
  std::vector<SimEvent> events;
  StepStats stats;
  bool result = false;
  /// Scheduling: the current slice's end, the job's time so far, the last whole job's time.
  Clock::time_point deadline = Clock::time_point::max();
  double job_s = 0.0, estimate_s = 0.0;
};

void ImplicitIntegrator::far_reset(Structure& st, const SoftBody& body,
                                   const IntegratorOptions& options) {
  auto ff = std::make_shared<FarField>(body);
  ff->generation = body.derived_generation();
  ff->constraints = body.constraint_edits();
  ff->options = options;
  ff->options.far_field_interval = 1;
  ff->options.sleeping = false;  // the copy's state is rewritten every period
  ff->options.dt_s = options.dt_s * double(options.far_field_interval);
  ff->body.clear_forces();
  FarField* raw = ff.get();
  ff->solver.team_ = std::make_shared<StepThreads>(kFarParts, [raw] {
    if (Fiber::current() == &raw->fiber && Clock::now() >= raw->deadline) Fiber::suspend();
  });
  ff->solver.prepare(ff->body, ff->options);
  if (st.multirate.far) ff->estimate_s = st.multirate.far->estimate_s;
  st.multirate.far = std::move(ff);  // a job part-way in the old one is run to its end
}

bool ImplicitIntegrator::far_follow(Structure& st, const SoftBody& body,
                                    const IntegratorOptions& options, bool untouched) {
  const FarField* ff = st.multirate.far.get();
  if (ff == nullptr || ff->generation != body.derived_generation() ||
      ff->constraints != body.constraint_edits() ||
      ff->options.dt_s != options.dt_s * double(options.far_field_interval)) {
    far_reset(st, body, options);
    return true;
  }
  if (!untouched || ff->body.frozen()) {
    far_sync(*st.multirate.far, body);
    return true;
  }
  return false;
}

void ImplicitIntegrator::far_sync(FarField& ff, const SoftBody& body) {
  finish_far_job(ff);
  ff.result = false;
  ff.events.clear();
  ff.body.positions() = body.positions();
  ff.body.velocities() = body.velocities();
  ff.body.unfreeze();
  ff.solver.wake(ff.body);
}

void ImplicitIntegrator::finish_far_job(FarField& ff) {
  ff.deadline = Clock::time_point::max();
  const Clock::time_point t0 = Clock::now();
  if (ff.fiber.part_way()) ff.fiber.resume();
  ff.job_s += std::chrono::duration<double>(Clock::now() - t0).count();
}

bool ImplicitIntegrator::far_apply(Structure& st, SoftBody& body, StepStats& stats,
                                   std::vector<SimEvent>& events, std::uint32_t body_index,
                                   std::uint64_t step_index) {
  FarField& ff = *st.multirate.far;
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
  // The far vertices take the job's end state; the near region's rows (its aggregates' during
  // the period) keep their own.
  const Structure::Multirate& mr = st.multirate;
  auto& x = body.positions();
  auto& v = body.velocities();
  const auto& fx = ff.body.positions();
  const auto& fv = ff.body.velocities();
  const std::vector<std::uint32_t>& rows = st.full.vertex;
  for (std::size_t r = 0; r < rows.size(); ++r) {
    if (mr.near[st.full.agg[r]]) continue;
    const std::uint32_t i = rows[r];
    x[i] = fx[i];
    v[i] = fv[i];
    ++stats.awake_vertices;  // moved by this step
  }
  return true;
}

void ImplicitIntegrator::far_start(Structure& st, const SoftBody& body, std::uint64_t step_index) {
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
    ff.stats = ff.solver.step(ff.body, ff.options, ff.events, 0, step_index);
    ff.result = true;
  });
}

void ImplicitIntegrator::far_slice(FarField& ff, std::size_t phase, std::size_t interval) {
  if (!ff.fiber.part_way()) return;
  if (phase + 1 >= interval) {
    finish_far_job(ff);
  } else {
    // An even share of what the estimate leaves, over the steps left in the period.
    const double left = std::max(ff.estimate_s - ff.job_s, 0.0);
    const double slice = std::max(kMinSliceS, left / double(interval - phase));
    const Clock::time_point t0 = Clock::now();
    ff.deadline =
        t0 + std::chrono::duration_cast<Clock::duration>(std::chrono::duration<double>(slice));
    ff.fiber.resume();
    ff.job_s += std::chrono::duration<double>(Clock::now() - t0).count();
  }
  if (!ff.fiber.part_way()) ff.estimate_s = ff.job_s;
}

}  // namespace bisturi::sim
