// Figures for the DLFL: insert_edge / delete_edge throughput on a 400-face and a million-face
// torus, the build time of the million-face torus, its memory per face and, with
// BISTURI_BENCH_OPENMESH, the same build in OpenMesh's TriMesh. A summary with the ratios follows
// the benchmark table.

#include <malloc.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <map>
#include <memory>
#include <optional>
#include <ostream>
#include <random>
#include <string>
#include <vector>

#include <benchmark/benchmark.h>

#include "collecting_reporter.h"

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/shapes.h"

#ifdef BISTURI_BENCH_OPENMESH
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#endif

namespace {

using bisturi::CornerId;
using bisturi::Dlfl;
using bisturi::FaceId;

constexpr std::int64_t kSmallFaces = 400;        // torus 20 x 10
constexpr std::int64_t kLargeFaces = 1'000'000;  // torus 1000 x 500
constexpr std::uint64_t kSeed = 20240611;

/// The triangulated torus of `faces` triangles with nu = 2 nv (faces = 4 nv^2).
bisturi::PolygonMesh torus(std::int64_t faces) {
  const auto nv = static_cast<std::size_t>(std::lround(std::sqrt(double(faces) / 4.0)));
  return bisturi::torus_mesh(40.0, 12.0, 2 * nv, nv, true);
}

/// Live heap bytes. Big blocks are mmapped by glibc and counted in hblkhd, not in uordblks,
/// so both are needed (uordblks alone misses most of a million-face mesh).
std::size_t heap_in_use() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

/// splitmix64 with a multiply-shift range reduction: cheap enough not to blur a ~50 ns op.
class Rng {
 public:
  explicit Rng(std::uint64_t seed) : state_(seed) {}
  std::uint32_t below(std::uint32_t n) {
    state_ += 0x9e3779b97f4a7c15ULL;
    std::uint64_t z = state_;
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return static_cast<std::uint32_t>(((z >> 32) * n) >> 32);
  }

 private:
  std::uint64_t state_;
};

/// One torus per size, shared by the operator benchmarks: each of them undoes every edge it
/// inserts, so the mesh keeps its faces (all triangles) and only the ids shuffle among them.
struct CachedMesh {
  explicit CachedMesh(Dlfl built) : dlfl(std::move(built)) {
    for (std::uint32_t i = 0; i < dlfl.face_capacity(); ++i) {
      if (dlfl.alive(FaceId(i))) faces.push_back(FaceId(i));
    }
  }
  Dlfl dlfl;
  std::vector<FaceId> faces;  // the live faces; split/undo and merge/undo keep this set alive
  std::int64_t pairs_done = 0;
};

std::map<std::int64_t, std::unique_ptr<CachedMesh>>& mesh_cache() {
  static std::map<std::int64_t, std::unique_ptr<CachedMesh>> cache;
  return cache;
}

CachedMesh& cached_torus(std::int64_t faces) {
  auto& slot = mesh_cache()[faces];
  if (!slot) {
    slot = std::make_unique<CachedMesh>(bisturi::build_oriented_manifold(torus(faces)));
    // The builder reserves exact sizes, so the first insert regrows the arrays once (a copy of
    // the whole mesh): done here, off the clock, as any long-lived mesh would have done it.
    Dlfl& d = slot->dlfl;
    const CornerId c = d.first_corner(slot->faces.front());
    d.delete_edge_pair(d.insert_edge(c, d.next(d.next(c))).side12);
  }
  return *slot;
}

// ---- insert_edge / delete_edge_pair ----

enum class Kind { kSplit, kMerge };
enum class Timed { kPair, kInsert, kDelete };

struct Ends {
  CornerId c1, c2;
};

/// Split: c and next(next(c)) of a triangle; the new edge cuts it into a digon and a triangle.
Ends split_ends(const Dlfl& d, FaceId f) {
  const CornerId c = d.first_corner(f);
  return {c, d.next(d.next(c))};
}

/// Merge: corners of two different faces, on different vertices (no self-loop).
Ends merge_ends(const Dlfl& d, FaceId f, FaceId g) {
  const CornerId c1 = d.first_corner(f);
  CornerId c2 = d.first_corner(g);
  if (d.vertex(c2) == d.vertex(c1)) c2 = d.next(c2);
  return {c1, c2};
}

/// insert_edge then delete_edge_pair of the new pair (which restores the mesh), one random face
/// (split) or two random faces anywhere on the mesh (merge) per iteration.
void BM_InsertDelete(benchmark::State& state, Kind kind) {
  CachedMesh& m = cached_torus(state.range(0));
  Dlfl& d = m.dlfl;
  const auto n = static_cast<std::uint32_t>(m.faces.size());
  Rng rng(kSeed);
  for (auto _ : state) {
    const std::uint32_t i = rng.below(n);
    Ends ends;
    if (kind == Kind::kSplit) {
      ends = split_ends(d, m.faces[i]);
    } else {
      std::uint32_t j = rng.below(n);
      if (j == i) j = (i + 1) % n;
      ends = merge_ends(d, m.faces[i], m.faces[j]);
    }
    const bisturi::InsertEdgeResult r = d.insert_edge(ends.c1, ends.c2);
    d.delete_edge_pair(r.side12);
  }
  m.pairs_done += state.iterations();
  state.SetItemsProcessed(state.iterations());
  state.counters["time_per_pair"] = benchmark::Counter(
      double(state.iterations()), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

/// insert_edge and delete_edge_pair timed apart: batches of inserts on distinct random faces,
/// then the deletes in reverse order, with the clock read around one of the two loops.
void BM_InsertOrDelete(benchmark::State& state, Kind kind, Timed timed) {
  CachedMesh& m = cached_torus(state.range(0));
  Dlfl& d = m.dlfl;
  // Distinct faces per batch, so no insert finds its face already cut by another.
  constexpr std::size_t kBatch = 128;
  const std::size_t faces_per_op = kind == Kind::kSplit ? 1 : 2;
  std::vector<FaceId> order = m.faces;
  std::mt19937_64 shuffle_rng(kSeed);
  std::size_t pos = order.size();
  std::vector<CornerId> sides(kBatch);
  using Clock = std::chrono::steady_clock;
  for (auto _ : state) {
    if (pos + kBatch * faces_per_op > order.size()) {
      std::shuffle(order.begin(), order.end(), shuffle_rng);
      pos = 0;
    }
    const auto t0 = Clock::now();
    for (std::size_t k = 0; k < kBatch; ++k) {
      const Ends ends = kind == Kind::kSplit
                            ? split_ends(d, order[pos + k])
                            : merge_ends(d, order[pos + 2 * k], order[pos + 2 * k + 1]);
      sides[k] = d.insert_edge(ends.c1, ends.c2).side12;
    }
    const auto t1 = Clock::now();
    for (std::size_t k = kBatch; k-- > 0;)
      d.delete_edge_pair(sides[k]);
    const auto t2 = Clock::now();
    pos += kBatch * faces_per_op;
    const auto elapsed = timed == Timed::kInsert ? t1 - t0 : t2 - t1;
    state.SetIterationTime(std::chrono::duration<double>(elapsed).count());
  }
  const auto ops = state.iterations() * static_cast<std::int64_t>(kBatch);
  m.pairs_done += ops;
  state.SetItemsProcessed(ops);
  state.counters["time_per_op"] =
      benchmark::Counter(double(ops), benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
}

// ---- build time and memory ----

void set_memory_counters(benchmark::State& state, std::size_t faces, std::size_t heap_bytes) {
  state.counters["faces"] = double(faces);
  state.counters["bytes_per_face"] = double(heap_bytes) / double(faces);
}

/// build_oriented_manifold of the torus (the polygon input is made outside the clock). Memory:
/// the live heap grown by the build while the Dlfl is alive and the builder's temporaries gone.
void BM_BuildDlfl(benchmark::State& state) {
  const bisturi::PolygonMesh mesh = torus(state.range(0));
  std::optional<Dlfl> dlfl;
  std::size_t heap = 0;
  std::size_t arrays = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const std::size_t before = heap_in_use();
    state.ResumeTiming();
    dlfl.emplace(bisturi::build_oriented_manifold(mesh));
    state.PauseTiming();
    heap = heap_in_use() - before;
    arrays = dlfl->memory_bytes();
    dlfl.reset();
    state.ResumeTiming();
  }
  set_memory_counters(state, mesh.face_count(), heap);
  state.counters["array_bytes_per_face"] = double(arrays) / double(mesh.face_count());
}

// ---- vertex -> face circulation ----

/// Every vertex's faces by walking its rotation with rot_next (no allocation).
void BM_VertexFacesRotNext(benchmark::State& state) {
  const Dlfl& d = cached_torus(state.range(0)).dlfl;
  for (auto _ : state) {
    std::uint64_t sum = 0;
    for (std::uint32_t v = 0; v < d.vertex_capacity(); ++v) {
      const CornerId start = d.rotation_corner(d.first_rotation(bisturi::VertexId(v)));
      CornerId c = start;
      do {
        sum += d.face(c).idx;
        c = d.rot_next(c);
      } while (c != start);
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(d.vertex_capacity()));
}

/// The same through the faces_around_vertex query (which returns vectors).
void BM_FacesAroundVertex(benchmark::State& state) {
  const Dlfl& d = cached_torus(state.range(0)).dlfl;
  for (auto _ : state) {
    std::uint64_t sum = 0;
    for (std::uint32_t v = 0; v < d.vertex_capacity(); ++v) {
      for (const auto& rotation : bisturi::faces_around_vertex(d, bisturi::VertexId(v))) {
        for (FaceId f : rotation)
          sum += f.idx;
      }
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(d.vertex_capacity()));
}

#ifdef BISTURI_BENCH_OPENMESH

struct DoubleTraits : OpenMesh::DefaultTraits {
  typedef OpenMesh::Vec3d Point;
};
using TriMeshF = OpenMesh::TriMesh_ArrayKernelT<>;
using TriMeshD = OpenMesh::TriMesh_ArrayKernelT<DoubleTraits>;

/// Undirected edges of a polygon mesh, for OpenMesh's reserve().
std::size_t count_edges(const bisturi::PolygonMesh& mesh) {
  std::vector<std::uint64_t> keys;
  keys.reserve(mesh.indices.size());
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto poly = mesh.face(f);
    for (std::size_t k = 0; k < poly.size(); ++k) {
      const std::uint64_t a = poly[k];
      const std::uint64_t b = poly[(k + 1) % poly.size()];
      keys.push_back(std::min(a, b) << 32 | std::max(a, b));
    }
  }
  std::sort(keys.begin(), keys.end());
  return static_cast<std::size_t>(std::unique(keys.begin(), keys.end()) - keys.begin());
}

/// The same positions and triangles through add_vertex / add_face. Our builder reserves exact
/// sizes, so OpenMesh is measured both as usually filled (arrays grow by doubling) and after
/// reserve(V, E, F) (exact arrays, the like-for-like figure).
template <class Mesh>
void fill_openmesh(Mesh& om, const bisturi::PolygonMesh& mesh, std::size_t reserve_edges) {
  using Scalar = typename Mesh::Point::value_type;
  if (reserve_edges > 0) om.reserve(mesh.positions.size(), reserve_edges, mesh.face_count());
  std::vector<typename Mesh::VertexHandle> handles;
  handles.reserve(mesh.positions.size());
  for (const auto& p : mesh.positions) {
    handles.push_back(om.add_vertex(typename Mesh::Point(
        static_cast<Scalar>(p.x), static_cast<Scalar>(p.y), static_cast<Scalar>(p.z))));
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto t = mesh.face(f);
    om.add_face(handles[t[0]], handles[t[1]], handles[t[2]]);
  }
}

template <class Mesh>
void BM_BuildOpenMesh(benchmark::State& state, bool reserve) {
  const bisturi::PolygonMesh mesh = torus(state.range(0));
  const std::size_t reserve_edges = reserve ? count_edges(mesh) : 0;
  std::optional<Mesh> om;
  std::size_t heap = 0;
  for (auto _ : state) {
    state.PauseTiming();
    const std::size_t before = heap_in_use();
    state.ResumeTiming();
    om.emplace();
    fill_openmesh(*om, mesh, reserve_edges);
    state.PauseTiming();
    heap = heap_in_use() - before;
    if (om->n_faces() != mesh.face_count()) state.SkipWithError("OpenMesh refused faces");
    om.reset();
    state.ResumeTiming();
  }
  set_memory_counters(state, mesh.face_count(), heap);
}

void BM_OpenMeshVertexFaces(benchmark::State& state) {
  static std::map<std::int64_t, std::unique_ptr<TriMeshF>> cache;
  auto& om = cache[state.range(0)];
  if (!om) {
    om = std::make_unique<TriMeshF>();
    fill_openmesh(*om, torus(state.range(0)), 0);
  }
  for (auto _ : state) {
    std::uint64_t sum = 0;
    for (auto v : om->vertices()) {
      for (auto f : om->vf_range(v))
        sum += static_cast<std::uint64_t>(f.idx());
    }
    benchmark::DoNotOptimize(sum);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(om->n_vertices()));
}

#endif  // BISTURI_BENCH_OPENMESH

// ---- closing summary ----

using bisturi::bench::CollectingReporter;

template <class... Args>
std::string format(const char* fmt, Args... args) {
  char buf[256];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

/// Nanoseconds per operation: the counters are already per op (inverted rates, in seconds).
std::optional<double> ns_per_op(const CollectingReporter& r, const std::string& name) {
  auto v = r.counter(name, "time_per_pair");
  if (!v) v = r.counter(name, "time_per_op");
  if (!v) return std::nullopt;
  return *v * 1e9;
}

void print_summary(CollectingReporter& r) {
  std::ostream& out = r.summary_stream();
  const std::string small = "/" + std::to_string(kSmallFaces);
  const std::string large = "/" + std::to_string(kLargeFaces);
  out << "\nSummary\n";
  const char* ops[][2] = {
      {"split_insert_delete", "split: insert + delete (pair)"},
      {"split_insert", "split: insert_edge alone"},
      {"split_delete", "split: delete_edge_pair alone"},
      {"merge_insert_delete", "merge: insert + delete (pair)"},
      {"merge_insert", "merge: insert_edge alone"},
      {"merge_delete", "merge: delete_edge_pair alone"},
  };
  std::string rows;
  for (const auto& [key, label] : ops) {
    const auto s = ns_per_op(r, std::string("dlfl/") + key + small);
    const auto l = ns_per_op(r, std::string("dlfl/") + key + large);
    if (!s || !l) continue;
    rows += format("  %-31s %9.1f ns %7.2f M/s %9.1f ns %7.2f M/s %11.2f\n", label, *s, 1e3 / *s,
                   *l, 1e3 / *l, *l / *s);
  }
  if (!rows.empty()) {
    const double growth = double(kLargeFaces) / double(kSmallFaces);
    out << format("  insert_edge / delete_edge_pair on random faces, %lld vs %lld faces (%.0fx).\n",
                  static_cast<long long>(kSmallFaces), static_cast<long long>(kLargeFaces), growth)
        << "  The work per op is O(face length); large/small is the price of cache and TLB\n"
        << format("  misses once the mesh outgrows the caches (an O(mesh) op would show %.0fx).\n",
                  growth)
        << format("  %-31s %22lld faces %20lld faces  large/small\n", "",
                  static_cast<long long>(kSmallFaces), static_cast<long long>(kLargeFaces))
        << rows;
  }

  if (const auto* build = r.find("dlfl/build" + large)) {
    out << format("  build_oriented_manifold, %lld faces: %.0f ms wall, %.0f ms CPU\n",
                  static_cast<long long>(kLargeFaces), build->GetAdjustedRealTime(),
                  build->GetAdjustedCPUTime());
  }
  const auto ours = r.counter("dlfl/build" + large, "bytes_per_face");
  const auto arrays = r.counter("dlfl/build" + large, "array_bytes_per_face");
  if (!ours || !arrays) return;
  out << "  memory, live heap bytes per face (mallinfo2 uordblks + hblkhd around the build):\n"
      << format("    %-36s %6.1f  (memory_bytes(): %.1f)\n", "bisturi Dlfl", *ours, *arrays);
  const char* peers[][2] = {
      {"openmesh_float/build", "OpenMesh TriMesh, float"},
      {"openmesh_float/build_reserved", "OpenMesh TriMesh, float, reserved"},
      {"openmesh_double/build", "OpenMesh TriMesh, double"},
      {"openmesh_double/build_reserved", "OpenMesh TriMesh, double, reserved"},
  };
  bool any_peer = false;
  for (const auto& [key, label] : peers) {
    const auto theirs = r.counter(key + large, "bytes_per_face");
    const auto* run = r.find(key + large);
    if (!theirs || run == nullptr) continue;
    any_peer = true;
    out << format("    %-36s %6.1f  bisturi/OpenMesh %.2f; build %.0f ms wall, %.0f ms CPU\n",
                  label, *theirs, *ours / *theirs, run->GetAdjustedRealTime(),
                  run->GetAdjustedCPUTime());
  }
  if (any_peer) out << "    goal: bisturi within 1.30x of OpenMesh's TriMesh\n";
  const auto* rot = r.find("dlfl/vertex_faces_rot_next" + large);
  const auto* query = r.find("dlfl/faces_around_vertex" + large);
  const auto* peer = r.find("openmesh_float/vertex_faces" + large);
  if (rot != nullptr) {
    out << format("  faces around every vertex (CPU): rot_next walk %.1f ms",
                  rot->GetAdjustedCPUTime());
    if (query != nullptr) {
      out << format(", faces_around_vertex %.1f ms", query->GetAdjustedCPUTime());
    }
    if (peer != nullptr) {
      out << format(", OpenMesh vf_range %.1f ms (rot_next/OpenMesh %.2f)",
                    peer->GetAdjustedCPUTime(),
                    rot->GetAdjustedCPUTime() / peer->GetAdjustedCPUTime());
    }
    out << "\n";
  }
}

/// The shared meshes must still be valid and whole after all the insert/delete pairs.
bool check_cached_meshes(std::ostream& out) {
  bool ok = true;
  for (const auto& [faces, m] : mesh_cache()) {
    const bisturi::ValidationReport report = bisturi::validate(m->dlfl);
    bool whole = m->dlfl.num_faces() == m->faces.size();
    for (FaceId f : m->faces)
      whole = whole && bisturi::face_valence(m->dlfl, f) == 3;
    out << "  check " << faces << "-face torus after " << m->pairs_done << " insert/delete pairs: "
        << (report.ok() && whole ? "valid, all faces triangles" : "BROKEN") << "\n";
    if (!report.ok()) out << report.summary() << "\n";
    ok = ok && report.ok() && whole;
  }
  return ok;
}

void register_benchmarks() {
  using benchmark::RegisterBenchmark;
  // A million-face build takes about a second: a few iterations are enough.
  RegisterBenchmark("dlfl/build", BM_BuildDlfl)
      ->Arg(kLargeFaces)
      ->Iterations(2)
      ->Unit(benchmark::kMillisecond);
#ifdef BISTURI_BENCH_OPENMESH
  for (const bool reserve : {false, true}) {
    const std::string suffix = reserve ? "/build_reserved" : "/build";
    RegisterBenchmark(("openmesh_float" + suffix).c_str(), BM_BuildOpenMesh<TriMeshF>, reserve)
        ->Arg(kLargeFaces)
        ->Iterations(2)
        ->Unit(benchmark::kMillisecond);
    RegisterBenchmark(("openmesh_double" + suffix).c_str(), BM_BuildOpenMesh<TriMeshD>, reserve)
        ->Arg(kLargeFaces)
        ->Iterations(2)
        ->Unit(benchmark::kMillisecond);
  }
#endif
  RegisterBenchmark("dlfl/vertex_faces_rot_next", BM_VertexFacesRotNext)
      ->Arg(kLargeFaces)
      ->Unit(benchmark::kMillisecond);
  RegisterBenchmark("dlfl/faces_around_vertex", BM_FacesAroundVertex)
      ->Arg(kLargeFaces)
      ->Unit(benchmark::kMillisecond);
#ifdef BISTURI_BENCH_OPENMESH
  RegisterBenchmark("openmesh_float/vertex_faces", BM_OpenMeshVertexFaces)
      ->Arg(kLargeFaces)
      ->Unit(benchmark::kMillisecond);
#endif
  // Last, so that the sweeps above see the cached mesh as built.
  const struct {
    const char* name;
    Kind kind;
    Timed timed;
  } ops[] = {
      {"dlfl/split_insert_delete", Kind::kSplit, Timed::kPair},
      {"dlfl/split_insert", Kind::kSplit, Timed::kInsert},
      {"dlfl/split_delete", Kind::kSplit, Timed::kDelete},
      {"dlfl/merge_insert_delete", Kind::kMerge, Timed::kPair},
      {"dlfl/merge_insert", Kind::kMerge, Timed::kInsert},
      {"dlfl/merge_delete", Kind::kMerge, Timed::kDelete},
  };
  for (const auto& op : ops) {
    benchmark::internal::Benchmark* b =
        op.timed == Timed::kPair
            ? RegisterBenchmark(op.name, BM_InsertDelete, op.kind)
            : RegisterBenchmark(op.name, BM_InsertOrDelete, op.kind, op.timed)->UseManualTime();
    b->Arg(kSmallFaces)->Arg(kLargeFaces);
  }
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  register_benchmarks();
  CollectingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  if (!reporter.empty()) print_summary(reporter);
  const bool ok = check_cached_meshes(reporter.summary_stream());
  benchmark::Shutdown();
  return ok ? 0 : 1;
}
