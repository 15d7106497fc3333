// Isosurface extraction throughput (million voxels per second): marching cubes into an indexed
// triangle mesh, and the full DLFL build (written directly from the cell tables; for comparison
// also through the mesh and build_oriented_manifold, and through import_polygons), on a 256^3
// sphere, a 256^3 gyroid and a 512^3 sphere.
// With BISTURI_BENCH_VTK, vtkFlyingEdges3D and vtkMarchingCubes run on the same float arrays in
// the same binary (one thread and two threads through vtkSMPTools); a summary with the ratios
// follows the table. Run by hand (build/bin/extract_bench); not registered with CTest.

#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <numbers>
#include <string>

#include <benchmark/benchmark.h>

#include "collecting_reporter.h"

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/volume/marching_cubes.h"

#ifdef BISTURI_BENCH_VTK
#include "vtk_runner.h"
#endif

namespace {

using bisturi::Grid;

enum class Shape { kSphere, kGyroid };

/// Sphere: R - |p - c| with R = 0.4 n; gyroid: sin x cos y + sin y cos z + sin z cos x with four
/// periods across the volume. Iso value 0 for both.
const Grid<float>& volume(Shape shape, std::int64_t n) {
  static std::map<std::pair<int, std::int64_t>, std::unique_ptr<Grid<float>>> cache;
  auto& slot = cache[{static_cast<int>(shape), n}];
  if (slot) return *slot;
  slot = std::make_unique<Grid<float>>();
  Grid<float>& g = *slot;
  g.geometry.dims = {n, n, n};
  g.geometry.spacing = glm::dvec3(0.5);
  g.values.resize(g.geometry.voxel_count());
  const double c = 0.5 * double(n - 1) + 0.123, r = 0.4 * double(n);
  const double w = 2.0 * std::numbers::pi * 4.0 / double(n);
  std::size_t idx = 0;
  for (std::int64_t k = 0; k < n; ++k) {
    for (std::int64_t j = 0; j < n; ++j) {
      for (std::int64_t i = 0; i < n; ++i, ++idx) {
        double v;
        if (shape == Shape::kSphere) {
          const double x = double(i) - c, y = double(j) - c, z = double(k) - c;
          v = r - std::sqrt(x * x + y * y + z * z);
        } else {
          const double x = w * double(i), y = w * double(j), z = w * double(k);
          v = std::sin(x) * std::cos(y) + std::sin(y) * std::cos(z) + std::sin(z) * std::cos(x);
        }
        g.values[idx] = static_cast<float>(v);
      }
    }
  }
  return g;
}

void set_rate(benchmark::State& state, const Grid<float>& g) {
  state.counters["Mvox/s"] = benchmark::Counter(static_cast<double>(g.geometry.voxel_count()) *
                                                    1e-6 * static_cast<double>(state.iterations()),
                                                benchmark::Counter::kIsRate);
}

void BM_Mesh(benchmark::State& state, Shape shape, std::int64_t n) {
  const Grid<float>& g = volume(shape, n);
  bisturi::ExtractionStats stats;
  for (auto _ : state) {
    bisturi::PolygonMesh mesh = bisturi::extract_isosurface_mesh(g, {}, &stats);
    benchmark::DoNotOptimize(mesh.indices.data());
  }
  set_rate(state, g);
  state.counters["triangles"] = static_cast<double>(stats.triangles);
  state.counters["ambiguous"] = static_cast<double>(stats.ambiguous_faces);
}

void BM_MeshOctree(benchmark::State& state, Shape shape, std::int64_t n) {
  const Grid<float>& g = volume(shape, n);
  bisturi::IsoSurfaceOptions options;
  options.build_octree = true;
  bisturi::ExtractionStats stats;
  for (auto _ : state) {
    bisturi::PolygonMesh mesh = bisturi::extract_isosurface_mesh(g, options, &stats);
    benchmark::DoNotOptimize(mesh.indices.data());
  }
  set_rate(state, g);
  state.counters["octree_s"] = stats.octree_seconds;
  state.counters["skipped"] = static_cast<double>(stats.leaves_skipped);
}

void BM_Dlfl(benchmark::State& state, Shape shape, std::int64_t n) {
  const Grid<float>& g = volume(shape, n);
  bisturi::ExtractionStats stats;
  for (auto _ : state) {
    bisturi::Dlfl mesh = bisturi::extract_isosurface(g, {}, &stats);
    benchmark::DoNotOptimize(mesh.num_faces());
  }
  set_rate(state, g);
  state.counters["extract_s"] = stats.extract_seconds;
  state.counters["build_s"] = stats.build_seconds;
}

// For comparison: the triangle mesh, then build_oriented_manifold (the rotation system and the
// bulk assembler: the way extract_isosurface built the DLFL before it wrote it directly).
void BM_DlflViaMesh(benchmark::State& state, Shape shape, std::int64_t n) {
  const Grid<float>& g = volume(shape, n);
  for (auto _ : state) {
    const bisturi::PolygonMesh mesh = bisturi::extract_isosurface_mesh(g);
    bisturi::Dlfl dlfl = bisturi::build_oriented_manifold(mesh);
    benchmark::DoNotOptimize(dlfl.num_faces());
  }
  set_rate(state, g);
}

// For comparison: the same triangles through import_polygons (weld, orientation, edge groups).
void BM_DlflBulk(benchmark::State& state, Shape shape, std::int64_t n) {
  const Grid<float>& g = volume(shape, n);
  for (auto _ : state) {
    bisturi::PolygonMesh mesh = bisturi::extract_isosurface_mesh(g);
    bisturi::ImportResult result = bisturi::import_polygons(mesh, true);
    benchmark::DoNotOptimize(result.mesh.num_faces());
  }
  set_rate(state, g);
}

#ifdef BISTURI_BENCH_VTK
void BM_Vtk(benchmark::State& state, Shape shape, std::int64_t n, bool flying_edges) {
  const Grid<float>& g = volume(shape, n);
  bisturi::bench::vtk_set_threads(static_cast<int>(state.range(0)));
  std::int64_t triangles = 0;
  for (auto _ : state) {
    triangles = bisturi::bench::vtk_extract(g.values.data(), n, 0.0f, flying_edges);
    benchmark::DoNotOptimize(triangles);
  }
  set_rate(state, g);
  state.counters["triangles"] = static_cast<double>(triangles);
}
#endif

void register_all() {
  struct Volume {
    const char* name;
    Shape shape;
    std::int64_t n;
  };
  for (const Volume& v :
       {Volume{"sphere256", Shape::kSphere, 256}, Volume{"gyroid256", Shape::kGyroid, 256},
        Volume{"sphere512", Shape::kSphere, 512}}) {
    const std::string suffix = std::string("/") + v.name;
    benchmark::RegisterBenchmark(("mesh" + suffix).c_str(), BM_Mesh, v.shape, v.n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("mesh_octree" + suffix).c_str(), BM_MeshOctree, v.shape, v.n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("dlfl" + suffix).c_str(), BM_Dlfl, v.shape, v.n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("dlfl_via_mesh" + suffix).c_str(), BM_DlflViaMesh, v.shape, v.n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("dlfl_bulk_import" + suffix).c_str(), BM_DlflBulk, v.shape, v.n)
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
#ifdef BISTURI_BENCH_VTK
    benchmark::RegisterBenchmark(("vtk_flying_edges" + suffix).c_str(), BM_Vtk, v.shape, v.n, true)
        ->Arg(1)
        ->Arg(2)
        ->ArgName("threads")
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
    benchmark::RegisterBenchmark(("vtk_marching_cubes" + suffix).c_str(), BM_Vtk, v.shape, v.n,
                                 false)
        ->Arg(1)
        ->ArgName("threads")
        ->Unit(benchmark::kMillisecond)
        ->UseRealTime();
#endif
  }
}

}  // namespace

int main(int argc, char** argv) {
  register_all();
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  bisturi::bench::CollectingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  if (reporter.empty()) return 0;
  std::ostream& out = reporter.summary_stream();
  out << "\nMillion voxels per second (same run):\n";
  auto rate = [&](const std::string& name) {
    return reporter.counter(name, "Mvox/s").value_or(0.0);
  };
  for (const std::string v : {"sphere256", "gyroid256", "sphere512"}) {
    char line[256];
    std::snprintf(line, sizeof line,
                  "  %-10s mesh %7.1f  mesh+octree build %7.1f  dlfl %7.1f  dlfl (via mesh) %7.1f"
                  "  dlfl (bulk import) %7.1f",
                  v.c_str(), rate("mesh/" + v), rate("mesh_octree/" + v), rate("dlfl/" + v),
                  rate("dlfl_via_mesh/" + v), rate("dlfl_bulk_import/" + v));
    out << line;
#ifdef BISTURI_BENCH_VTK
    const double fe1 = rate("vtk_flying_edges/" + v + "/threads:1");
    const double fe2 = rate("vtk_flying_edges/" + v + "/threads:2");
    const double mc1 = rate("vtk_marching_cubes/" + v + "/threads:1");
    std::snprintf(line, sizeof line,
                  "\n             vtkFlyingEdges3D 1t %7.1f 2t %7.1f  vtkMarchingCubes 1t %7.1f"
                  "  mesh/FE1 %.2f  dlfl/FE1 %.2f  dlfl/FE2 %.2f  mesh/MC %.2f",
                  fe1, fe2, mc1, fe1 > 0 ? rate("mesh/" + v) / fe1 : 0.0,
                  fe1 > 0 ? rate("dlfl/" + v) / fe1 : 0.0, fe2 > 0 ? rate("dlfl/" + v) / fe2 : 0.0,
                  mc1 > 0 ? rate("mesh/" + v) / mc1 : 0.0);
    out << line;
#endif
    out << "\n";
  }
  return 0;
}
