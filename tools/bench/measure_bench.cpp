// Plane cuts for vessel measurement: time per cut and faces touched on a vessel mesh
// of about 1M faces (a torus-shaped bent vessel, minor radius 12.5 mm, extracted at 0.25 mm),
// through the edge hierarchy against a brute-force test of every edge, and with
// BISTURI_BENCH_VTK against vtkCutter + vtkStripper on a vtkPolyData built from the same arrays.
// Each cut is a meridian plane (two loops, one on each side of the torus); 16 planes rotate.
// A summary with the ratios measured in the same run follows the table.

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdio>
#include <numbers>
#include <vector>

#include "bisturi/scene/measure/plane_cut.h"
#include "bisturi/scene/measure/section_measures.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "collecting_reporter.h"
#ifdef BISTURI_BENCH_VTK
#include "measure_vtk.h"
#endif

namespace {

using bisturi::Plane;

struct Fixture {
  bisturi::PolygonMesh polygons;
  bisturi::Dlfl mesh;
  glm::dvec3 centre{0.0};
  std::vector<Plane> planes;
};

const Fixture& fixture() {
  static const Fixture f = [] {
    Fixture x;
    bisturi::PhantomOptions p;
    p.shape = bisturi::PhantomShape::Torus;
    p.dims = {590, 590, 110};
    p.spacing = glm::dvec3(0.25);
    p.a = 60.0;
    p.b = 12.5;
    const bisturi::Volume v = bisturi::make_phantom(p);
    bisturi::IsoSurfaceOptions iso;
    iso.placement = bisturi::VertexPlacement::Cubic;
    x.polygons = bisturi::extract_isosurface_mesh(v, iso);
    x.mesh = bisturi::build_oriented_manifold(x.polygons);
    x.centre = glm::dvec3(p.dims[0] - 1, p.dims[1] - 1, p.dims[2] - 1) * p.spacing * 0.5;
    for (int i = 0; i < 16; ++i) {
      const double phi = 2.0 * std::numbers::pi * i / 16.0 + 0.1;
      x.planes.push_back({x.centre, glm::dvec3(-std::sin(phi), std::cos(phi), 0.0)});
    }
    std::fprintf(stderr, "vessel mesh: %zu faces, %zu edges\n", x.mesh.num_faces(),
                 x.mesh.num_edges());
    return x;
  }();
  return f;
}

const bisturi::CutIndex& index() {
  static const bisturi::CutIndex i(fixture().mesh);
  return i;
}

void BM_BuildIndex(benchmark::State& state) {
  const Fixture& f = fixture();
  for (auto _ : state) {
    const bisturi::CutIndex i(f.mesh);
    benchmark::DoNotOptimize(i.node_count());
  }
  state.counters["edges"] = double(f.mesh.num_edges());
}

void BM_IndexCut(benchmark::State& state) {
  const Fixture& f = fixture();
  const bisturi::CutIndex& idx = index();
  bisturi::CutOptions o;
  o.surface_points = state.range(0) != 0;
  std::size_t k = 0, faces = 0, loops = 0, tested = 0, cuts = 0;
  for (auto _ : state) {
    const bisturi::PlaneCut c = idx.cut(f.planes[k++ % f.planes.size()], o);
    faces += c.faces_touched;
    loops += c.loops.size();
    tested += c.edges_tested;
    ++cuts;
  }
  state.counters["faces_touched"] = double(faces) / double(cuts);
  state.counters["loops"] = double(loops) / double(cuts);
  state.counters["edges_tested"] = double(tested) / double(cuts);
}

void BM_IndexCutMeasure(benchmark::State& state) {
  const Fixture& f = fixture();
  const bisturi::CutIndex& idx = index();
  std::size_t k = 0;
  for (auto _ : state) {
    const bisturi::PlaneCut c = idx.cut(f.planes[k++ % f.planes.size()]);
    benchmark::DoNotOptimize(bisturi::measure_cut(c));
  }
}

void BM_BruteForceCut(benchmark::State& state) {
  const Fixture& f = fixture();
  std::size_t k = 0, faces = 0, cuts = 0;
  for (auto _ : state) {
    const bisturi::PlaneCut c =
        bisturi::cut_plane_brute_force(f.mesh, f.planes[k++ % f.planes.size()]);
    faces += c.faces_touched;
    ++cuts;
  }
  state.counters["faces_touched"] = double(faces) / double(cuts);
  state.counters["edges_tested"] = double(f.mesh.num_edges());
}

#ifdef BISTURI_BENCH_VTK
void BM_VtkCutterStripper(benchmark::State& state) {
  const Fixture& f = fixture();
  static bisturi::bench::VtkCutMesh vtk(
      &f.polygons.positions[0].x, static_cast<std::int64_t>(f.polygons.positions.size()),
      f.polygons.indices.data(), static_cast<std::int64_t>(f.polygons.face_count()));
  std::size_t k = 0, loops = 0, cuts = 0;
  for (auto _ : state) {
    const Plane& p = f.planes[k++ % f.planes.size()];
    const double point[3] = {p.point.x, p.point.y, p.point.z};
    const double normal[3] = {p.normal.x, p.normal.y, p.normal.z};
    std::int64_t points = 0;
    loops += static_cast<std::size_t>(vtk.cut(point, normal, &points));
    ++cuts;
  }
  state.counters["loops"] = double(loops) / double(cuts);
  state.counters["faces_touched"] = double(f.polygons.face_count());  // vtkCutter reads all
}
#endif

}  // namespace

BENCHMARK(BM_BuildIndex)->Unit(benchmark::kMillisecond)->Iterations(3);
BENCHMARK(BM_IndexCut)->Arg(1)->Arg(0)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_IndexCutMeasure)->Unit(benchmark::kMicrosecond);
BENCHMARK(BM_BruteForceCut)->Unit(benchmark::kMillisecond);
#ifdef BISTURI_BENCH_VTK
BENCHMARK(BM_VtkCutterStripper)->Unit(benchmark::kMillisecond);
#endif

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  bisturi::bench::CollectingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  if (reporter.empty()) return 0;
  std::ostream& out = reporter.summary_stream();
  auto ns = [&](const std::string& name) {
    const auto* run = reporter.find(name);
    return run == nullptr ? 0.0
                          : run->GetAdjustedRealTime() * 1e9 /
                                benchmark::GetTimeUnitMultiplier(run->time_unit);
  };
  const double index_ns = ns("BM_IndexCut/1");
  char line[256];
  std::snprintf(line, sizeof line,
                "\nPer cut (same run): index %.1f us (without surface points %.1f us, with "
                "measures %.1f us), brute force %.2f ms: brute/index %.1fx",
                index_ns * 1e-3, ns("BM_IndexCut/0") * 1e-3, ns("BM_IndexCutMeasure") * 1e-3,
                ns("BM_BruteForceCut") * 1e-6,
                index_ns > 0 ? ns("BM_BruteForceCut") / index_ns : 0.0);
  out << line;
#ifdef BISTURI_BENCH_VTK
  std::snprintf(
      line, sizeof line,
      "\n  vtkCutter + vtkStripper %.2f ms: vtk/index %.1fx, vtk/(index + measures) %.1fx",
      ns("BM_VtkCutterStripper") * 1e-6, index_ns > 0 ? ns("BM_VtkCutterStripper") / index_ns : 0.0,
      ns("BM_IndexCutMeasure") > 0 ? ns("BM_VtkCutterStripper") / ns("BM_IndexCutMeasure") : 0.0);
  out << line;
#endif
  out << "\n";
  return 0;
}
