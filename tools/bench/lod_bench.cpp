// Figures for levels of detail: QEM decimation of a 200k-triangle torus to 10%, and subdivision
// of a 10k-face control mesh to two levels, refined once (topology + first interpolation) against
// the per-frame update that only re-interpolates. Run by hand (build/bin/lod_bench).

#include <chrono>
#include <cmath>
#include <cstdint>
#include <vector>

#include <benchmark/benchmark.h>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/lod/decimate.h"
#include "bisturi/scene/lod/smooth.h"
#include "bisturi/scene/lod/subdivision.h"
#include "bisturi/scene/shapes.h"

namespace {

using bisturi::Dlfl;
namespace lod = bisturi::lod;

/// Triangulated torus of 2 nu nv = `faces` triangles with nu = 2 nv.
bisturi::PolygonMesh torus_triangles(std::int64_t faces) {
  const auto nv = static_cast<std::size_t>(std::lround(std::sqrt(double(faces) / 4.0)));
  return bisturi::torus_mesh(40.0, 12.0, 2 * nv, nv, true);
}

void BM_Decimate(benchmark::State& state) {
  const bisturi::PolygonMesh mesh = torus_triangles(state.range(0));
  lod::DecimateStats stats;
  for (auto _ : state) {
    Dlfl d = bisturi::build_oriented_manifold(mesh);  // not timed
    lod::DecimateOptions opt;
    opt.target_faces = static_cast<std::size_t>(state.range(0) / 10);
    const auto t0 = std::chrono::steady_clock::now();
    stats = lod::decimate(d, opt);
    const auto t1 = std::chrono::steady_clock::now();
    state.SetIterationTime(std::chrono::duration<double>(t1 - t0).count());
  }
  state.counters["faces_in"] = double(stats.initial_faces);
  state.counters["faces_out"] = double(stats.final_faces);
  state.counters["refused"] = double(stats.rejected_topology + stats.rejected_geometry);
  state.counters["max_error_mm"] = stats.max_error;
  state.counters["collapses_per_s"] = benchmark::Counter(
      double(stats.collapses) * double(state.iterations()), benchmark::Counter::kIsRate);
}
BENCHMARK(BM_Decimate)->Arg(200'000)->UseManualTime()->Unit(benchmark::kMillisecond);

void BM_SmoothTaubin(benchmark::State& state) {
  Dlfl d = bisturi::build_oriented_manifold(torus_triangles(state.range(0)));
  lod::SmoothOptions opt;
  opt.iterations = 10;
  for (auto _ : state)
    lod::smooth_taubin(d, opt);
  state.counters["faces"] = double(state.range(0));
}
BENCHMARK(BM_SmoothTaubin)->Arg(200'000)->Unit(benchmark::kMillisecond);

/// 10k control faces: quads (Catmull-Clark) with range(1) == 0, triangles (Loop) otherwise.
Dlfl control_mesh(bool triangles) {
  return triangles
             ? bisturi::build_oriented_manifold(bisturi::torus_mesh(40.0, 12.0, 100, 50, true))
             : bisturi::build_oriented_manifold(bisturi::torus_mesh(40.0, 12.0, 100, 100, false));
}

void BM_SubdivisionRefineOnce(benchmark::State& state) {
  const Dlfl control = control_mesh(state.range(1) != 0);
  lod::SubdivisionOptions opt;
  opt.levels = static_cast<int>(state.range(0));
  std::size_t faces = 0;
  for (auto _ : state) {
    const lod::SubdivisionLevels levels(control, opt);
    faces = levels.face_count(opt.levels);
    benchmark::DoNotOptimize(levels.positions(opt.levels).data());
  }
  state.counters["fine_faces"] = double(faces);
}
BENCHMARK(BM_SubdivisionRefineOnce)
    ->ArgsProduct({{2}, {0, 1}})
    ->ArgNames({"levels", "loop"})
    ->Unit(benchmark::kMillisecond);

void BM_SubdivisionUpdate(benchmark::State& state) {
  Dlfl control = control_mesh(state.range(1) != 0);
  lod::SubdivisionOptions opt;
  opt.levels = static_cast<int>(state.range(0));
  lod::SubdivisionLevels levels(control, opt);
  std::vector<Dlfl::Vec3> moved(levels.control_vertices().size());
  double phase = 0.0;
  for (auto _ : state) {
    // A new frame: every control vertex moves a little (not the part being measured, but cheap).
    phase += 0.01;
    for (std::size_t i = 0; i < moved.size(); ++i) {
      const auto& p = control.position(levels.control_vertices()[i]);
      moved[i] = p + Dlfl::Vec3(0.0, 0.0, std::sin(phase + 0.001 * p.x));
    }
    levels.update(moved);
    benchmark::DoNotOptimize(levels.positions(opt.levels).data());
  }
  state.counters["fine_faces"] = double(levels.face_count(opt.levels));
}
BENCHMARK(BM_SubdivisionUpdate)
    ->ArgsProduct({{2}, {0, 1}})
    ->ArgNames({"levels", "loop"})
    ->Unit(benchmark::kMillisecond);

}  // namespace

BENCHMARK_MAIN();
