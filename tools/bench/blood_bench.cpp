// Blood (sim/blood.h): one step of 1/90 s for N particles resting and flowing on a rigid slab,
// and the liquid surface drawn round them (runtime/render/liquid_surface.h), against the display
// period each must fit in (the ratio is the share of the period one takes on one core).

#include <benchmark/benchmark.h>

#include <chrono>

#include "bisturi/runtime/render/liquid_surface.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/sim/blood.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/world.h"

namespace bisturi::sim {
namespace {

constexpr double kDisplayPeriod_s = 1.0 / 90.0;

/// A rigid 80 x 80 x 4 mm slab of tissue.
SimWorld slab_world() {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  SoftBody body(build_oriented_manifold(cube_mesh(Dlfl::Vec3(0.0), 80.0)), Material{});
  for (auto& p : body.positions())
    p.z *= 4.0 / 80.0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
    body.set_anchored(VertexId(i), true);
  world.add_body(std::move(body));
  world.prepare();
  return world;
}

/// Times per iteration as a share of the display period.
void count_share_of_display_period(benchmark::State& state) {
  state.counters["share_of_display_period"] =
      benchmark::Counter(static_cast<double>(state.iterations()) * kDisplayPeriod_s,
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

/// 500 to 5000 particles, timed by hand (the setup pours them), in milliseconds, over the same
/// 30 iterations every run (the blood goes on settling while it is timed, and gets cheaper: a
/// run of more iterations would time an easier state).
void particle_counts(benchmark::internal::Benchmark* b) {
  b->Arg(500)->Arg(1000)->Arg(2000)->Arg(5000)->UseManualTime()->Unit(benchmark::kMillisecond);
  b->Iterations(30);
}

/// Blood poured from four points 10 mm above the slab until there are `particles`.
Blood poured_blood(SimWorld& world, std::size_t particles, unsigned threads = 1) {
  BloodOptions options;
  options.max_particles = particles;
  options.threads = threads;
  options.floor_z_m = -0.05;
  options.field_min_m = glm::dvec3(-0.2);
  options.field_max_m = glm::dvec3(0.2);
  Blood blood(options);
  const BloodSurface surface{&world.body(0), &world.bvh(0)};
  std::vector<BloodSource> sources;
  for (const double x : {0.025, 0.055})
    for (const double y : {0.025, 0.055})
      sources.push_back({{x, y, 0.014}, {0.0, 0.0, -1.0}});
  while (blood.positions().size() < particles) {
    (void)blood.emit(sources, 50e-6, 0.2, kDisplayPeriod_s);
    blood.step(kDisplayPeriod_s, {&surface, 1});
  }
  return blood;
}

/// One step on `threads` threads (the same blood, bit for bit, with one or two).
void blood_step(benchmark::State& state, unsigned threads) {
  const auto particles = static_cast<std::size_t>(state.range(0));
  SimWorld world = slab_world();
  Blood blood = poured_blood(world, particles, threads);
  const BloodSurface surface{&world.body(0), &world.bvh(0)};
  for (auto _ : state) {
    const auto begin = std::chrono::steady_clock::now();
    blood.step(kDisplayPeriod_s, {&surface, 1});
    state.SetIterationTime(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count());
  }
  state.counters["particles"] = static_cast<double>(blood.positions().size());
  state.counters["pooled"] = static_cast<double>(blood.counts().pooled);
  count_share_of_display_period(state);
}

void BM_BloodStep(benchmark::State& state) {
  blood_step(state, 1);
}
BENCHMARK(BM_BloodStep)->Apply(particle_counts);

/// Two threads: what a step takes when a second core is free for it.
void BM_BloodStepTwoThreads(benchmark::State& state) {
  blood_step(state, 2);
}
BENCHMARK(BM_BloodStepTwoThreads)->Apply(particle_counts);

void BM_BloodLiquidSurface(benchmark::State& state) {
  const auto particles = static_cast<std::size_t>(state.range(0));
  SimWorld world = slab_world();
  const Blood blood = poured_blood(world, particles);
  std::vector<glm::dvec3> centres_mm;
  for (const glm::dvec3& p : blood.positions())
    centres_mm.push_back(sim_to_scene(p));
  render::LiquidSurface liquid;
  for (auto _ : state) {
    const auto begin = std::chrono::steady_clock::now();
    benchmark::DoNotOptimize(liquid.update(centres_mm).num_faces());
    state.SetIterationTime(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - begin).count());
  }
  state.counters["particles"] = static_cast<double>(centres_mm.size());
  state.counters["faces"] = static_cast<double>(liquid.mesh().num_faces());
  count_share_of_display_period(state);
}
BENCHMARK(BM_BloodLiquidSurface)->Apply(particle_counts);

}  // namespace
}  // namespace bisturi::sim

BENCHMARK_MAIN();
