// The volume model in a world step (sim/volume/volume_body.h), on the default organ's size: a
// sphere of radius 28 mm (1 mm voxels) with its lower third anchored and the probe pressing
// 0..3 mm into its top and back at 2 Hz, as sim_bench's BM_FullStep does for the membrane.
// BM_VolumeBuild: building the volume (lattice, elements, embedding) at three cell sizes.
// BM_VolumeCut: a cut and a second one through the volume, and the split lattice's build.
// BM_VolumeStep: one 1 ms world step with the body stepped by its volume at three cell sizes:
// p50/p99, CG iterations, cells and nodes, and in the same run the same step with the body a
// spring membrane (surface_p50_us) and the ratio of the two p50s. BM_VolumeForceConvergence:
// the haptic force at dt = 1 ms against dt / 16. BM_VolumeBetweenSteps: the force on the
// haptic tick between two 500 Hz steps, by the volume's compliance and by its alternatives.
// Run by hand: build/bin/volume_bench [--benchmark_filter=...].

#include <benchmark/benchmark.h>

#include <chrono>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/sim/tissue.h"
#include "bisturi/sim/volume/hex_lattice.h"
#include "bisturi/sim/world.h"
#include "sim_bench_support.h"

namespace {

using namespace bisturi;
using namespace bisturi::sim;
using bench::percentile;

/// The default organ's size.
const bench::Shape& organ() {
  return bench::sphere(28.0);
}

SoftBody anchored_sphere() {
  const bench::Shape& shape = organ();
  SoftBody body(build_oriented_manifold(shape.polygons), Material{});
  bench::anchor_below(body, (shape.centre_mm - shape.radius_mm / 3.0) * 1e-3);
  return body;
}

VolumeOptions liver_cells(double cell_mm) {
  VolumeOptions o;
  o.cell_m = cell_mm * 1e-3;
  o.material = tissue_preset("liver").material;
  return o;
}

/// The step times (us) of `steps` probe steps after 200 to settle.
std::vector<double> step_times(SimWorld& world, int steps, double* cg_mean = nullptr) {
  std::uint64_t s = 0;
  for (; s < 200; ++s)
    world.step(bench::probe_tip(organ(), double(s)));
  std::vector<double> us;
  double cg = 0.0;
  for (int k = 0; k < steps; ++k, ++s) {
    const auto t0 = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(world.step(bench::probe_tip(organ(), double(s))));
    us.push_back(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count() *
                 1e6);
    cg += world.last_stats(0).cg_iterations;
  }
  if (cg_mean) *cg_mean = cg / steps;
  return us;
}

void BM_VolumeBuild(benchmark::State& state) {
  const SoftBody body = anchored_sphere();
  const double cell_mm = double(state.range(0));
  std::size_t cells = 0, nodes = 0;
  for (auto _ : state) {
    VolumeBody volume(body, liver_cells(cell_mm));
    cells = volume.volume().lattice().cells.size();
    nodes = volume.volume().positions().size();
    benchmark::DoNotOptimize(volume);
  }
  state.counters["vertices"] = double(body.mesh().num_vertices());
  state.counters["cells"] = double(cells);
  state.counters["nodes"] = double(nodes);
}
BENCHMARK(BM_VolumeBuild)->Arg(4)->Arg(6)->Arg(8)->Unit(benchmark::kMillisecond)->Iterations(5);

void BM_VolumeStep(benchmark::State& state) {
  const double cell_mm = double(state.range(0));
  SimWorld surface;
  surface.add_body(anchored_sphere());
  surface.prepare();
  const std::vector<double> membrane = step_times(surface, 1000);

  SimWorld world;
  world.add_body(anchored_sphere());
  world.set_volume(0, liver_cells(cell_mm));
  world.prepare();
  std::vector<double> samples;
  double cg = 0.0;
  for (auto _ : state) {
    samples = step_times(world, 1000, &cg);
    state.SetIterationTime(percentile(samples, 0.5) * 1e-6);
  }
  const double p50 = percentile(samples, 0.50);
  state.counters["cells"] = double(world.volume(0)->volume().lattice().cells.size());
  state.counters["nodes"] = double(world.volume(0)->volume().positions().size());
  state.counters["p50_us"] = p50;
  state.counters["p99_us"] = percentile(samples, 0.99);
  state.counters["cg_iters"] = cg;
  state.counters["surface_p50_us"] = percentile(membrane, 0.50);
  state.counters["volume_over_surface"] = p50 / percentile(membrane, 0.50);
  state.counters["events"] = double(world.take_events().size());
}
BENCHMARK(BM_VolumeStep)
    ->Arg(4)
    ->Arg(6)
    ->Arg(8)
    ->UseManualTime()
    ->Unit(benchmark::kMicrosecond)
    ->Iterations(1);

// How the haptic force depends on the step length with the volume (6 mm cells): 1.6 s of the
// probing, lowered by the argument (um; 2000 keeps the probe in firm contact), with dt = 1 ms / k
// for k = 1, 2, 4, 8, 16 (the device held over a millisecond's steps). Counters per k: the RMS
// force (force_k_mN) and the RMS difference from the k = 16 run against that run's RMS force
// (diff_k).
/// The organ stepped by its volume of 6 mm cells at steps of dt.
std::unique_ptr<SimWorld> probed_world(double dt) {
  WorldOptions options;
  options.integrator.dt_s = dt;
  auto world = std::make_unique<SimWorld>(options);
  world->add_body(anchored_sphere());
  world->set_volume(0, liver_cells(6.0));
  world->prepare();
  return world;
}

void BM_VolumeForceConvergence(benchmark::State& state) {
  const double lower = double(state.range(0)) * 1e-6;
  bench::force_convergence(
      state, probed_world, [&](int ms) { return bench::probe_tip(organ(), ms, lower); }, 1600);
}
BENCHMARK(BM_VolumeForceConvergence)->Arg(0)->Arg(2000)->Iterations(1)->Unit(benchmark::kSecond);

// The force between steps: the tissue at 500 Hz (dt = 2 ms), the haptic tick at 1 kHz, as the
// liver scene runs. On the tick between two steps the force is the step's plus a stiffness
// times the motion since it of the tip relative to the patch, by one of: the coupling in series
// with the volume's compliance under the patch, the patch going on at its speed
// (compliance_moving); the same with the patch held (compliance); the coupling in series with a
// Hertz contact's tangent stiffness (hertz); the coupling alone (coupling); no stiffness, the
// step's force held (hold). stepped_1ms: a world stepped at every tick, for scale. Against a
// world stepped at dt = 1/16 ms, over the in-between ticks, each against that run's RMS force
// there: the RMS difference (the name alone) and the RMS of how far the in-between force is
// from the mean of the steps either side (rough_*; reference_rough for the dt/16 world itself):
// what a hand feels as a 500 Hz buzz. 6 mm cells, 1.6 s of the probing, lowered by the argument
// (um; 2000 keeps the probe in firm contact).
void BM_VolumeBetweenSteps(benchmark::State& state) {
  const double lower = double(state.range(0)) * 1e-6;
  const ElasticMaterial liver = tissue_preset("liver").material;
  const double e_star =
      liver.youngs_modulus_kPa * 1e3 / (1.0 - liver.poisson_ratio * liver.poisson_ratio);
  enum { kCompliance, kMoving, kHertz, kCoupling, kHold, kStepped, kWays };
  const char* names[kWays] = {"compliance", "compliance_moving", "hertz", "coupling",
                              "hold",       "stepped_1ms"};
  for (auto _ : state) {
    auto reference = probed_world(1e-3 / 16.0);
    auto coarse = probed_world(2e-3);
    auto every_tick = probed_world(1e-3);
    const double coupling = coarse->options().haptic.coupling_N_per_m;
    const double radius = coarse->options().haptic.probe_radius_m;
    double reference2 = 0.0, reference_rough2 = 0.0, diff2[kWays] = {}, rough2[kWays] = {};
    std::vector<glm::dvec3> between(kWays, glm::dvec3(0.0));
    glm::dvec3 exact_between(0.0), exact_before(0.0), step_tip(0.0);
    bool have_between = false;
    HapticOutput step;
    for (int ms = 0; ms < 1600; ++ms) {
      const glm::dvec3 tip = bench::probe_tip(organ(), ms, lower);
      HapticOutput exact;
      for (int j = 0; j < 16; ++j)
        exact = reference->step(tip);
      const HapticOutput stepped = every_tick->step(tip);
      if (ms % 2 == 0) {
        const glm::dvec3 last_step_force = step.force_N;
        step = coarse->step(tip);
        step_tip = tip;
        if (have_between) {
          for (int w = 0; w < kWays; ++w) {
            const glm::dvec3 r = between[w] - 0.5 * (last_step_force + step.force_N);
            rough2[w] += glm::dot(r, r);
          }
          const glm::dvec3 r = exact_between - 0.5 * (exact_before + exact.force_N);
          reference_rough2 += glm::dot(r, r);
        }
        exact_before = exact.force_N;
        continue;
      }
      const glm::dvec3 moved = step_tip - tip;
      const glm::dvec3 patch_moved = 1e-3 * step.patch_velocity_m_s;
      const double compliant = 1.0 / (1.0 / coupling + step.compliance_m_per_N);
      const double hertz =
          2.0 * e_star * std::cbrt(3.0 * glm::length(step.force_N) * radius / (4.0 * e_star));
      const glm::dvec3 added[kHold + 1] = {compliant * moved, compliant * (moved + patch_moved),
                                           hertz * coupling / (hertz + coupling) * moved,
                                           coupling * moved, glm::dvec3(0.0)};
      for (int w = 0; w <= kHold; ++w)
        between[w] = step.contact ? step.force_N + added[w] : glm::dvec3(0.0);
      between[kStepped] = stepped.force_N;
      exact_between = exact.force_N;
      have_between = true;
      reference2 += glm::dot(exact.force_N, exact.force_N);
      for (int w = 0; w < kWays; ++w)
        diff2[w] += glm::dot(between[w] - exact.force_N, between[w] - exact.force_N);
    }
    const double scale = std::max(reference2, 1e-300);
    state.counters["rms_force_mN"] = 1e3 * std::sqrt(reference2 / 800.0);
    state.counters["reference_rough"] = std::sqrt(reference_rough2 / scale);
    for (int w = 0; w < kWays; ++w) {
      state.counters[names[w]] = std::sqrt(diff2[w] / scale);
      state.counters[std::string("rough_") + names[w]] = std::sqrt(rough2[w] / scale);
    }
  }
}
BENCHMARK(BM_VolumeBetweenSteps)->Arg(0)->Arg(2000)->Iterations(1)->Unit(benchmark::kSecond);

// A cut through the organ's volume (cells of the argument, mm, split in 8 along the blade as the
// liver scene's cut_refine = 2 does): SimWorld::cut with the blade's tips, 1 cm long and 6 mm
// deep across the top, then a second one 8 mm beside it (the lattice split again along both and
// parted along the first again): first_cut_ms, second_cut_ms (medians). In the same run, the
// split lattice built from the inside shares the volume sampled as it was built (what a cut
// builds on) and by sampling the solid again: lattice_shared_ms, lattice_sampled_ms, and
// sampled_over_shared.
double timed_cut_ms(SimWorld& world, double y_m) {
  const bench::Shape& shape = organ();
  const double c = shape.centre_mm * 1e-3, r = shape.radius_mm * 1e-3;
  std::vector<glm::dvec3> blade, tips;
  for (int i = 0; i <= 10; ++i) {
    const double x = c - 0.005 + 0.001 * i;
    const double z = c + std::sqrt(r * r - (x - c) * (x - c) - (y_m - c) * (y_m - c));
    blade.emplace_back(x, y_m, z + 0.0005);
    tips.emplace_back(x, y_m, z - 0.006);
  }
  const auto t0 = std::chrono::steady_clock::now();
  benchmark::DoNotOptimize(world.cut(0, blade, {}, tips));
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

void BM_VolumeCut(benchmark::State& state) {
  VolumeOptions options = liver_cells(double(state.range(0)));
  options.cut_refine_factor = 2;
  const double c = organ().centre_mm * 1e-3;
  const glm::dvec3 away(1.0);  // the probe far from the organ
  std::vector<double> first, second, shared, sampled;
  std::size_t cells = 0;
  for (auto _ : state) {
    SimWorld world;
    world.add_body(anchored_sphere());
    world.set_volume(0, options);
    world.prepare();
    for (int s = 0; s < 10; ++s)
      world.step(away);
    first.push_back(timed_cut_ms(world, c));
    for (int s = 0; s < 10; ++s)
      world.step(away);
    second.push_back(timed_cut_ms(world, c + 0.008));
    cells = world.volume(0)->volume().lattice().cells.size();
    state.SetIterationTime(first.back() * 1e-3);
  }
  // The lattice alone, with a box along the first cut.
  const SoftBody body = anchored_sphere();
  std::vector<std::array<std::uint32_t, 3>> triangles(body.triangles().indices.size() / 3);
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (std::size_t k = 0; k < 3; ++k)
      triangles[t][k] = body.triangles().indices[3 * t + k];
  TwoLevelOptions two;
  two.coarse_m = options.cell_m;
  two.factor = 2;
  const double top = c + organ().radius_mm * 1e-3;
  two.refine = {
      {glm::dvec3(c - 0.006, c - 0.002, top - 0.008), glm::dvec3(c + 0.006, c + 0.002, top)}};
  const FineShares shares = two_level_fine_shares(body.positions(), triangles, two);
  for (int k = 0; k < 5; ++k) {
    for (const bool with_shares : {true, false}) {
      const auto t0 = std::chrono::steady_clock::now();
      benchmark::DoNotOptimize(build_two_level_lattice(body.positions(), triangles, two, {},
                                                       with_shares ? &shares : nullptr));
      (with_shares ? shared : sampled)
          .push_back(
              std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
                  .count());
    }
  }
  state.counters["cells_after"] = double(cells);
  state.counters["first_cut_ms"] = percentile(first, 0.5);
  state.counters["second_cut_ms"] = percentile(second, 0.5);
  state.counters["lattice_shared_ms"] = percentile(shared, 0.5);
  state.counters["lattice_sampled_ms"] = percentile(sampled, 0.5);
  state.counters["sampled_over_shared"] = percentile(sampled, 0.5) / percentile(shared, 0.5);
}
BENCHMARK(BM_VolumeCut)
    ->Arg(6)
    ->Arg(18)
    ->UseManualTime()
    ->Unit(benchmark::kMillisecond)
    ->Iterations(5);

}  // namespace

BENCHMARK_MAIN();
