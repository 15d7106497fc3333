// Soft-tissue simulation: one full haptic-rate step (haptic proxy force with its
// reaction, implicit integrator with the divergence guard, BVH refit) on closed spheres of about
// 2k, 20k and 100k vertices (phantom + marching cubes, 1 mm voxels), single thread (Embree with
// threads=1); p50 and p99 of the step time come out as counters, with the mean number of CG
// iterations and the last relative residual. And the time to apply one 5 cm cut (blade points
// along an arc over the top of the 20k-vertex sphere), BVH rebuild included. BM_TwoBodies: the
// headset session's shape of work (first step with and without SimWorld::prepare(), steady
// step, a cut tick and the step after it). BM_Refit: the Embree refit of a sphere on its own;
// BM_RefitPart: the same when only a region of it moves. BM_MakeBody: a SoftBody made from its
// solid. BM_Multirate*: multirate stepping's time and fidelity; BM_ForceConvergence: how the
// haptic force depends on the step length. BM_FastTip: what the haptic sweep (continuous
// collision) costs a step under a 1 m/s gesture.
// Run by hand: build/bin/sim_bench [--benchmark_filter=...]. Goal: p99 <= 1 ms at 20k.

#include <benchmark/benchmark.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <map>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <glm/geometric.hpp>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/sim/collision.h"
#include "bisturi/sim/tissue_contact.h"
#include "bisturi/sim/world.h"
#include "sim_bench_support.h"

namespace {

using namespace bisturi;
using namespace bisturi::sim;
using bench::anchor_below;
using bench::percentile;
using bench::probe_tip;
using bench::Shape;
using bench::sphere;

/// Radii that give about 2k, 20k and 100k vertices.
double radius_for(std::int64_t vertices) {
  switch (vertices) {
    case 2000:
      return 10.0;
    case 20000:
      return 32.0;
    default:
      return 71.0;
  }
}

/// One world step with the tip at device_m, timed: its wall time in microseconds.
double timed_step_us(SimWorld& world, const glm::dvec3& device_m) {
  const auto t0 = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(world.step(device_m));
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() * 1e6;
}

/// The bench sphere in `world`, default material, its lower third anchored; returns its index.
std::uint32_t add_bench_sphere(SimWorld& world, const Shape& shape) {
  const std::uint32_t id =
      world.add_body(SoftBody(build_oriented_manifold(shape.polygons), Material{}));
  anchor_below(world.body(id), shape.centre_mm * 1e-3 - shape.radius_mm * 1e-3 / 3.0);
  return id;
}

// Full step: the probe presses 0..3 mm into the top of the sphere and back (a 2 Hz sine), the
// lower third is anchored, gravity on, default material and integrator options. The second
// argument is the thread count (1: single thread; 0: every core for the integrator and Embree).
void full_step(benchmark::State& state, std::int64_t vertices, bool all, int interval,
               bool bound = false) {
  const Shape& shape = sphere(radius_for(vertices));
  WorldOptions options;
  const unsigned cores = std::max(1u, std::thread::hardware_concurrency());
  options.embree_threads = all ? 0 : 1;
  options.integrator.threads = all ? cores : 1;
  options.integrator.far_field_interval = interval;
  if (bound) {
    options.integrator.spring_hessian = SpringHessian::Bound;
    options.integrator.cg_warm_start = true;
  }
  SimWorld world(options);
  const std::uint32_t id = add_bench_sphere(world, shape);
  const SoftBody& body = world.body(id);
  std::uint64_t s = 0;
  auto device = [&] { return probe_tip(shape, double(s)); };
  for (int w = 0; w < 200; ++w, ++s)
    world.step(device());  // settle the warm start
  std::vector<double> samples;
  double cg = 0.0;
  int cg_max = 0;
  double residual = 0.0, residual_sum = 0.0, awake = 0.0;
  std::vector<double> period_starts, others;
  for (auto _ : state) {
    const double us = timed_step_us(world, device());
    state.SetIterationTime(us * 1e-6);
    samples.push_back(us);
    // Multirate: the steps that start a far-field period (they end its last job, apply the
    // result to the near region's neighbours and start the next job) apart.
    (interval > 1 && s % std::uint64_t(interval) == 0 ? period_starts : others).push_back(us);
    cg += world.last_stats(id).cg_iterations;
    cg_max = std::max(cg_max, world.last_stats(id).cg_iterations);
    residual = world.last_stats(id).relative_residual;
    residual_sum += residual;
    const StepStats& st = world.last_stats(id);
    awake += st.free_vertices > 0 ? double(st.awake_vertices) / double(st.free_vertices) : 0.0;
    ++s;
  }
  state.counters["vertices"] = double(body.mesh().num_vertices());
  state.counters["springs"] = double(body.springs().size());
  state.counters["p50_us"] = percentile(samples, 0.50);
  state.counters["p99_us"] = percentile(samples, 0.99);
  state.counters["cg_iters"] = cg / double(std::max<std::size_t>(samples.size(), 1));
  state.counters["cg_max"] = cg_max;
  state.counters["mean_residual"] = residual_sum / double(std::max<std::size_t>(samples.size(), 1));
  state.counters["events"] = double(world.take_events().size());
  state.counters["awake"] = awake / double(std::max<std::size_t>(samples.size(), 1));
  if (interval > 1) {
    state.counters["start_p50_us"] = percentile(period_starts, 0.50);
    state.counters["start_p99_us"] = percentile(period_starts, 0.99);
    state.counters["other_p99_us"] = percentile(others, 0.99);
  }
}

void BM_FullStep(benchmark::State& state) {
  full_step(state, state.range(0), state.range(1) == 0, 1);
}
BENCHMARK(BM_FullStep)
    ->Args({2000, 1})
    ->Args({20000, 1})
    ->Args({100000, 1})
    ->Args({2000, 0})
    ->Args({20000, 0})
    ->Args({100000, 0})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(3000);

// The same scene with multirate stepping (IntegratorOptions::far_field_interval = the second
// argument): the near region every step, and a slice of the far field's longer step, whose
// result is applied over the next period. One thread (the far field's solve runs in a
// fiber on the calling thread); Embree with one thread. start_*: the steps that start a period.
void BM_Multirate(benchmark::State& state) {
  full_step(state, state.range(0), false, static_cast<int>(state.range(1)));
}
BENCHMARK(BM_Multirate)
    ->Args({2000, 8})
    ->Args({20000, 8})
    ->Args({20000, 16})
    ->Args({20000, 32})
    ->Args({100000, 16})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(3000);

// The peer of BM_FullStep and BM_Multirate in the same run: the springs' bound Hessian k I with
// the warm start (the solver before the clamped Hessian), single-rate (second argument 1) or
// multirate with that interval.
void BM_StepBound(benchmark::State& state) {
  full_step(state, state.range(0), false, static_cast<int>(state.range(1)), true);
}
BENCHMARK(BM_StepBound)
    ->Args({2000, 1})
    ->Args({20000, 1})
    ->Args({20000, 32})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(3000);

// What multirate stepping changes, against what the step length changes: the bench scene of
// BM_FullStep for 3.2 s of the 2 Hz probing, from the rest shape or after settling (third
// argument: steps with the probe away first), run three times: single-rate with dt / 4 (the
// reference: four steps per millisecond, the device held over them), single-rate with dt, and
// multirate with dt and the interval (second argument). Counters, each for the single-rate run
// (single_*) and the multirate one (multi_*) against the reference: the RMS of the haptic force's
// difference over the run against the reference force's RMS; at the end the RMS distance of the
// vertices within 10 mm of the probe (near) and beyond (far) against the RMS displacement from
// rest of the reference there. And each run's RMS haptic force (*_force_rms_N).
void BM_MultirateAccuracy(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  const double c = shape.centre_mm * 1e-3;
  const double r = shape.radius_mm * 1e-3;
  auto make = [&](int interval, int per_ms) {
    WorldOptions options;
    options.embree_threads = 1;
    options.integrator.far_field_interval = interval;
    options.integrator.dt_s = 1e-3 / per_ms;
    auto world = std::make_unique<SimWorld>(options);
    add_bench_sphere(*world, shape);
    return world;
  };
  constexpr int kFine = 4;
  for (auto _ : state) {
    auto reference = make(1, kFine);
    auto single = make(1, 1);
    auto multi = make(1, 1);
    // All settle single-rate for the third argument's milliseconds with the probe away, then
    // the third switches over.
    const glm::dvec3 away(c, c, c + r + 0.01);
    for (std::int64_t s = 0; s < state.range(2); ++s) {
      for (int k = 0; k < kFine; ++k)
        reference->step(away);
      single->step(away);
      multi->step(away);
    }
    multi->options().integrator.far_field_interval = static_cast<int>(state.range(1));
    double single_diff2 = 0.0, multi_diff2 = 0.0, force2 = 0.0, single_force2 = 0.0,
           multi_force2 = 0.0;
    for (int s = 0; s < 3200; ++s) {
      const glm::dvec3 tip = probe_tip(shape, s);
      glm::dvec3 f;
      for (int k = 0; k < kFine; ++k)
        f = reference->step(tip).force_N;
      const glm::dvec3 a = single->step(tip).force_N, b = multi->step(tip).force_N;
      single_diff2 += glm::dot(a - f, a - f);
      multi_diff2 += glm::dot(b - f, b - f);
      force2 += glm::dot(f, f);
      single_force2 += glm::dot(a, a);
      multi_force2 += glm::dot(b, b);
    }
    const SoftBody& ref = reference->body(0);
    const glm::dvec3 top(c, c, c + r);
    // Per region (0 near, 1 far): the reference's squared displacements, and each run's squared
    // distances to it.
    double moved2[2] = {0.0, 0.0}, single2[2] = {0.0, 0.0}, multi2[2] = {0.0, 0.0};
    for (std::uint32_t i = 0; i < ref.mesh().vertex_capacity(); ++i) {
      const VertexId v(i);
      if (!ref.mesh().alive(v)) continue;
      const int region = glm::length(ref.rest_position(v) - top) < 0.010 ? 0 : 1;
      const glm::dvec3 x = ref.position(v);
      moved2[region] += glm::dot(x - ref.rest_position(v), x - ref.rest_position(v));
      const glm::dvec3 ds = single->body(0).position(v) - x, dm = multi->body(0).position(v) - x;
      single2[region] += glm::dot(ds, ds);
      multi2[region] += glm::dot(dm, dm);
    }
    auto ratio = [](double a2, double b2) { return std::sqrt(a2 / std::max(b2, 1e-300)); };
    state.counters["reference_force_rms_N"] = std::sqrt(force2 / 3200.0);
    state.counters["single_force_rms_N"] = std::sqrt(single_force2 / 3200.0);
    state.counters["multi_force_rms_N"] = std::sqrt(multi_force2 / 3200.0);
    state.counters["single_force"] = ratio(single_diff2, force2);
    state.counters["multi_force"] = ratio(multi_diff2, force2);
    state.counters["single_near"] = ratio(single2[0], moved2[0]);
    state.counters["multi_near"] = ratio(multi2[0], moved2[0]);
    state.counters["single_far"] = ratio(single2[1], moved2[1]);
    state.counters["multi_far"] = ratio(multi2[1], moved2[1]);
    state.counters["events"] = double(multi->take_events().size() + single->take_events().size() +
                                      reference->take_events().size());
  }
}
BENCHMARK(BM_MultirateAccuracy)
    ->Args({2000, 2, 0})
    ->Args({2000, 8, 0})
    ->Args({2000, 8, 3000})
    ->Args({20000, 4, 0})
    ->Args({20000, 16, 0})
    ->Args({20000, 16, 3000})
    ->Args({20000, 32, 0})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// How the haptic force depends on the step length: the bench scene's 2 Hz probing for 3.2 s,
// its sine lowered by the second argument (um; 0 is BM_FullStep's, where the probe reaches
// 2 mm below the rest top of a sphere that sags away from it under gravity), run
// with dt = 1 ms / k for k = 1, 2, 4, 8, 16 (the device held over a millisecond's steps),
// single-rate or multirate with the third argument as far_field_interval. Counters per k: the RMS
// force (force_k_mN), the RMS difference from the k = 16 run against that run's RMS force (diff_k),
// and the contact changes per second (flips_k).
void BM_ForceConvergence(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  const double lower = double(state.range(1)) * 1e-6;
  const int interval = static_cast<int>(state.range(2));
  bench::force_convergence(
      state,
      [&](double dt) {
        WorldOptions options;
        options.embree_threads = 1;
        options.integrator.dt_s = dt;
        options.integrator.far_field_interval = interval;
        auto world = std::make_unique<SimWorld>(options);
        add_bench_sphere(*world, shape);
        return world;
      },
      [&](int ms) { return probe_tip(shape, ms, lower); }, 3200);
}
BENCHMARK(BM_ForceConvergence)
    ->Args({2000, 0, 1})
    ->Args({2000, 2000, 1})
    ->Args({2000, 0, 8})
    ->Args({2000, 2000, 8})
    ->Iterations(1)
    ->Unit(benchmark::kMillisecond);

// The Embree refit alone (part of BM_FullStep): every vertex moves by 1 um, then the surface BVH
// of the sphere is refitted (single thread).
void BM_Refit(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  SoftBody body(build_oriented_manifold(shape.polygons), Material{});
  CollisionDevice device(1);
  SurfaceBvh bvh(device, body);
  bvh.update(body);  // (commits nothing: no vertex moved since the build)
  double dz = 1e-6;
  for (auto _ : state) {
    for (auto& p : body.positions())
      p.z += dz;
    dz = -dz;
    bvh.update(body);
  }
  state.counters["triangles"] = double(body.triangles().size());
}
BENCHMARK(BM_Refit)->Arg(2000)->Arg(20000)->Arg(100000)->Unit(benchmark::kMicrosecond);

// The refit when only part of the sphere moves (what the integrator will do: the region around
// the instrument): the vertices within the second argument's radius (mm) of the sphere's top
// move by 1 um, then the BVH is refitted; only the patches holding them are (radius 0: nothing
// moves, the pass that finds what moved alone). Counters: the patches, those refitted per
// update, and the vertices moved.
void BM_RefitPart(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  SoftBody body(build_oriented_manifold(shape.polygons), Material{});
  const double c = shape.centre_mm * 1e-3, r = shape.radius_mm * 1e-3;
  const glm::dvec3 top(c, c, c + r);
  const double radius = double(state.range(1)) * 1e-3;
  std::vector<std::size_t> moved;
  for (std::size_t i = 0; i < body.positions().size(); ++i)
    if (glm::length(body.positions()[i] - top) <= radius) moved.push_back(i);
  CollisionDevice device(1);
  SurfaceBvh bvh(device, body);
  double dz = 1e-6;
  auto move = [&] {
    for (const std::size_t i : moved)
      body.positions()[i].z += dz;
    dz = -dz;
  };
  move();
  bvh.update(body);  // the region's patches refitted once before the clock
  for (auto _ : state) {
    move();
    bvh.update(body);
  }
  state.counters["patches"] = double(bvh.patch_count());
  state.counters["refitted"] = double(bvh.last_refitted_patches());
  state.counters["moved"] = double(moved.size());
}
BENCHMARK(BM_RefitPart)
    ->Args({2000, 8})
    ->Args({20000, 8})
    ->Args({20000, 0})
    ->Args({100000, 8})
    ->Unit(benchmark::kMicrosecond);

// The BVH built anew (what a cut costs the collision side: Embree cannot add primitives to a
// built scene).
void BM_Rebuild(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  SoftBody body(build_oriented_manifold(shape.polygons), Material{});
  CollisionDevice device(1);
  for (auto _ : state) {
    SurfaceBvh bvh(device, body);
    benchmark::DoNotOptimize(bvh.rebuilds());
  }
  state.counters["triangles"] = double(body.triangles().size());
}
BENCHMARK(BM_Rebuild)->Arg(2000)->Arg(20000)->Unit(benchmark::kMillisecond);

// The headset session's shape of work: two small bodies (an organ of about 800 vertices under
// the probe, a second body of about 800 vertices beside it), lower thirds anchored. Reports the
// first step after set-up (with SimWorld::prepare() when the argument is 1, without it when 0),
// the steady step while the probe presses (p50/p99), the tick of a 1 cm cut over the organ and
// the step after it.
void BM_TwoBodies(benchmark::State& state) {
  const bool prepare = state.range(0) != 0;
  const Shape& organ = sphere(7.0);
  const Shape& vessel = sphere(6.5);
  std::vector<double> first, second, samples, cut, after;
  int first_cg = 0;
  for (auto _ : state) {
    WorldOptions options;
    options.embree_threads = 1;
    SimWorld world(options);
    world.add_body(SoftBody(build_oriented_manifold(organ.polygons), Material{}));
    world.add_body(SoftBody(build_oriented_manifold(vessel.polygons), Material{}));
    const double c = organ.centre_mm * 1e-3;
    const double r = organ.radius_mm * 1e-3;
    // The second body 7 mm beside the first along x (as in the default scene).
    for (auto& p : world.body(1).positions())
      p.x += (organ.radius_mm + vessel.radius_mm + 7.0) * 1e-3;
    for (std::uint32_t b = 0; b < 2; ++b)
      anchor_below(world.body(b), c - r / 3.0);
    if (prepare) world.prepare();
    std::uint64_t s = 0;
    auto device = [&] { return probe_tip(organ, double(s)); };
    auto timed_step = [&] {
      const double us = timed_step_us(world, device());
      ++s;
      return us;
    };
    first.push_back(timed_step());
    first_cg = world.last_stats(0).cg_iterations + world.last_stats(1).cg_iterations;
    second.push_back(timed_step());
    for (int i = 0; i < 1000; ++i)
      samples.push_back(timed_step());
    const double half_angle = 0.005 / r;  // arc length 1 cm
    std::vector<glm::dvec3> points;
    for (int i = 0; i <= 4; ++i) {
      const double a = -half_angle + 2.0 * half_angle * i / 4.0;
      points.emplace_back(c + r * std::sin(a), c, c + r * std::cos(a));
    }
    const auto t0 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(world.cut(0, points));
    cut.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() *
                  1e6);
    after.push_back(timed_step());
    state.SetIterationTime(1e-6 * first.back());
  }
  state.counters["first_us"] = percentile(first, 0.5);
  state.counters["second_us"] = percentile(second, 0.5);
  state.counters["first_cg"] = first_cg;
  state.counters["p50_us"] = percentile(samples, 0.50);
  state.counters["p99_us"] = percentile(samples, 0.99);
  state.counters["cut_us"] = percentile(cut, 0.5);
  state.counters["after_cut_us"] = percentile(after, 0.5);
}
BENCHMARK(BM_TwoBodies)
    ->Arg(0)
    ->Arg(1)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(5);

// Tissue against tissue at its worst: a 20 mm sheet (the argument's cells per side) sunk
// 0.2 mm into the top of a 30 mm cube of twelve triangles, so every sheet triangle pairs with
// the face's two (2 x 2 x cells^2 pairs; at 80 about the 24,000 of a cut vessel lying on the
// bleeding scene's organ). From the same pairs (rtcCollide's, timed as the broad phase), the
// contacts both ways (the sheet's vertices out of the cube, the cube's out of the sheet) by
// sim::push_out (one nearest-surface query per vertex) against the peer: every (vertex,
// triangle) entry of the pairs sorted, the nearest of each vertex's paired triangles taken.
// Each of the cube's top corners is in a pair with every sheet triangle near it, which is what
// makes the peer dear. Both push every sheet vertex out; the peer also gives the cube's top
// corners a contact from the sheet's corner triangle 7 mm away, along its normal (push_out
// finds nothing within the 5 mm a contact reaches).
std::size_t peer_contacts(const SoftBody& from, PairSide side, const SoftBody& onto,
                          const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                          const ContactOptions& options,
                          std::vector<std::pair<std::uint32_t, std::uint32_t>>& vt) {
  const auto& fi = from.triangles().indices;
  const auto& oi = onto.triangles().indices;
  const auto& x = from.positions();
  const auto& xo = onto.positions();
  vt.clear();
  for (const auto& [first, second] : pairs) {
    const std::uint32_t tf = side == PairSide::First ? first : second;
    const std::uint32_t to = side == PairSide::First ? second : first;
    for (int c = 0; c < 3; ++c)
      vt.emplace_back(fi[3 * std::size_t{tf} + c], to);
  }
  std::sort(vt.begin(), vt.end());
  vt.erase(std::unique(vt.begin(), vt.end()), vt.end());
  std::size_t contacts = 0;
  for (std::size_t i = 0; i < vt.size();) {
    const std::uint32_t v = vt[i].first;
    double best = 1e30;
    glm::dvec3 best_q(0.0), best_n(0.0);
    for (; i < vt.size() && vt[i].first == v; ++i) {
      const std::size_t t = 3 * std::size_t{vt[i].second};
      const glm::dvec3 a = xo[oi[t]], b = xo[oi[t + 1]], c = xo[oi[t + 2]];
      glm::dvec3 bc;
      const glm::dvec3 q = closest_point_on_triangle(x[v], a, b, c, bc);
      if (glm::length(x[v] - q) < best) {
        best = glm::length(x[v] - q);
        best_q = q;
        best_n = onto.orientation() * glm::normalize(glm::cross(b - a, c - a));
      }
    }
    const double d = glm::dot(x[v] - best_q, best_n);
    contacts += d < options.margin_m && -d <= options.max_depth_m ? 1 : 0;
  }
  return contacts;
}

void BM_TissueContacts(benchmark::State& state) {
  const auto cells = static_cast<std::size_t>(state.range(0));
  CollisionDevice device(1);
  SoftBody cube(build_oriented_manifold(cube_mesh({0.0, 0.0, 0.0}, 30.0)), Material{});
  SoftBody sheet(build_oriented_manifold(grid_mesh(cells, cells, 20.0 / double(cells), false)),
                 Material{});
  for (auto& p : sheet.positions())
    p += glm::dvec3(0.005, 0.005, 0.0298);
  SurfaceBvh cube_bvh(device, cube);
  SurfaceBvh sheet_bvh(device, sheet);
  const ContactOptions options;
  ContactScratch scratch;
  std::vector<double> broad, queries, sorted;
  std::size_t pairs = 0, by_query = 0, by_sort = 0;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> vt;
  const auto us = [](auto a, auto b) {
    return std::chrono::duration<double, std::micro>(b - a).count();
  };
  for (auto _ : state) {
    sheet.clear_forces();
    cube.clear_forces();
    const auto t0 = std::chrono::steady_clock::now();
    const auto found = sheet_bvh.overlapping_triangles(sheet, cube_bvh, cube, options.margin_m);
    const auto t1 = std::chrono::steady_clock::now();
    by_query = push_out(sheet, PairSide::First, cube, cube_bvh, found, options, scratch) +
               push_out(cube, PairSide::Second, sheet, sheet_bvh, found, options, scratch);
    const auto t2 = std::chrono::steady_clock::now();
    by_sort = peer_contacts(sheet, PairSide::First, cube, found, options, vt) +
              peer_contacts(cube, PairSide::Second, sheet, found, options, vt);
    const auto t3 = std::chrono::steady_clock::now();
    pairs = found.size();
    broad.push_back(us(t0, t1));
    queries.push_back(us(t1, t2));
    sorted.push_back(us(t2, t3));
    state.SetIterationTime(1e-6 * queries.back());
  }
  state.counters["pairs"] = static_cast<double>(pairs);
  state.counters["broad_us"] = percentile(broad, 0.5);
  state.counters["queries_us"] = percentile(queries, 0.5);
  state.counters["sorted_pairs_us"] = percentile(sorted, 0.5);
  state.counters["peer_over_queries"] = percentile(sorted, 0.5) / percentile(queries, 0.5);
  state.counters["contacts"] = static_cast<double>(by_query);
  state.counters["peer_contacts"] = static_cast<double>(by_sort);
}
BENCHMARK(BM_TissueContacts)
    ->Arg(20)
    ->Arg(40)
    ->Arg(80)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(20);

// One 5 cm cut over the top of the 20k-vertex sphere (path, face splits, vertex splits, springs,
// masses, triangles and the BVH rebuilt), on a fresh body each time. SimWorld::cut in its two
// parts: the surface (cut_surface: path, splits, springs, masses, triangles) and the body's
// preparation for the next step (solver structure, coarse factor, BVH rebuild).
void BM_Cut5cm(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(20000));
  const double c = shape.centre_mm * 1e-3;
  const double r = shape.radius_mm * 1e-3;
  const double half_angle = 0.025 / r;  // arc length 5 cm
  std::vector<glm::dvec3> points;
  for (int i = 0; i <= 8; ++i) {
    const double a = -half_angle + 2.0 * half_angle * i / 8.0;
    points.emplace_back(c + r * std::sin(a), c, c + r * std::cos(a));
  }
  std::vector<double> samples, surface_ms, prepare_ms;
  std::size_t path = 0, patches = 0, rebuilt = 0;
  for (auto _ : state) {
    WorldOptions options;
    options.embree_threads = 1;
    SimWorld world(options);
    world.add_body(SoftBody(build_oriented_manifold(shape.polygons), Material{}));
    const auto t0 = std::chrono::steady_clock::now();
    const CutResult cut = cut_surface(world.body(0), points, CutOptions{});
    const auto t1 = std::chrono::steady_clock::now();
    world.prepare_body(0);
    const auto t2 = std::chrono::steady_clock::now();
    path = cut.path.size();
    patches = world.bvh(0).patch_count();
    rebuilt = world.bvh(0).last_rebuilt_patches();
    const double sec = std::chrono::duration<double>(t2 - t0).count();
    state.SetIterationTime(sec);
    samples.push_back(sec * 1e3);
    surface_ms.push_back(std::chrono::duration<double>(t1 - t0).count() * 1e3);
    prepare_ms.push_back(std::chrono::duration<double>(t2 - t1).count() * 1e3);
  }
  state.counters["surface_p50_ms"] = percentile(surface_ms, 0.50);
  state.counters["prepare_p50_ms"] = percentile(prepare_ms, 0.50);
  state.counters["path_vertices"] = double(path);
  state.counters["bvh_patches"] = double(patches);
  state.counters["patches_rebuilt"] = double(rebuilt);
  state.counters["p50_ms"] = percentile(samples, 0.50);
  state.counters["max_ms"] = percentile(samples, 1.0);
}
BENCHMARK(BM_Cut5cm)->UseManualTime()->Unit(benchmark::kMillisecond)->Iterations(10);

// Making a body: springs, masses, triangles and the solver's structure from the solid (what a
// session does for each organ it loads), the Dlfl's build from the polygons left out.
void BM_MakeBody(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  std::size_t springs = 0;
  for (auto _ : state) {
    state.PauseTiming();
    Dlfl mesh = build_oriented_manifold(shape.polygons);
    state.ResumeTiming();
    SoftBody body(std::move(mesh), Material{});
    springs = body.springs().size();
    benchmark::DoNotOptimize(springs);
  }
  state.counters["springs"] = double(springs);
}
BENCHMARK(BM_MakeBody)->Arg(2000)->Arg(20000)->Arg(100000)->Unit(benchmark::kMillisecond);

// A fast gesture: the tip plunges from 2 mm above the sphere's top to 6 mm into it and back at
// 1 m/s (1 mm per tick, a triangle wave), with the haptic sweep on (second argument 1) or off
// (0) in the same run: what continuous collision costs a full step, single thread.
void BM_FastTip(benchmark::State& state) {
  const Shape& shape = sphere(radius_for(state.range(0)));
  WorldOptions options;
  options.embree_threads = 1;
  options.integrator.threads = 1;
  options.haptic.continuous = state.range(1) != 0;
  SimWorld world(options);
  add_bench_sphere(world, shape);
  const double c = shape.centre_mm * 1e-3, r = shape.radius_mm * 1e-3;
  std::uint64_t s = 0;
  auto device = [&] {
    const int phase = static_cast<int>(s % 16);  // 8 ticks down, 8 up
    const double depth = 1e-3 * (phase < 8 ? phase : 16 - phase) - 0.002;
    return glm::dvec3(c, c, c + r - depth);
  };
  for (int w = 0; w < 64; ++w, ++s)
    world.step(device());
  std::vector<double> samples;
  for (auto _ : state) {
    const double us = timed_step_us(world, device());
    state.SetIterationTime(us * 1e-6);
    samples.push_back(us);
    ++s;
  }
  state.counters["p50_us"] = percentile(samples, 0.50);
  state.counters["p99_us"] = percentile(samples, 0.99);
}
BENCHMARK(BM_FastTip)
    ->Args({2000, 1})
    ->Args({2000, 0})
    ->Args({20000, 1})
    ->Args({20000, 0})
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(2000);

}  // namespace

BENCHMARK_MAIN();
