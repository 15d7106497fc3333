// Figures for building a solid from a mesh file: read_mesh_from_memory (parse) + import_polygons
// (construct) on a triangulated torus of 100k and 2M triangles, from an indexed binary PLY and
// from a binary STL soup, and (construct only) on the same torus with holes from an indexed PLY;
// with BISTURI_BENCH_OPENMESH / BISTURI_BENCH_CGAL the same build in OpenMesh's TriMesh and CGAL's
// Surface_mesh from the same in-memory arrays. After the table: a summary with faces/s and ratios,
// the faces each library keeps on non-manifold inputs, and the peak memory of the 2M build
// (measured in a forked child, so nothing before it pollutes it).
//
// Every timed section starts with the input already in memory and ends when the mesh is built;
// destruction and copies of the input are not timed (PauseTiming). The summary's figures are per
// CPU second (the machine is shared and noisy; process CPU time is what other work disturbs
// least), with the wall-clock figures beside them. The files are written to a temporary directory
// and read back once, so the parse works on the exact bytes a file on disk holds.
//
// --heap=fresh (default) or --heap=recycled picks how memory reaches each build (see "the heap
// regime" below); page_faults in the table counts the first touches of fresh pages per build,
// which in a virtual machine can cost more than the build's own work.
//
// Usage: import_bench [--heap=fresh|recycled] [Google Benchmark flags]

#include <malloc.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <new>
#include <optional>
#include <ostream>
#include <span>
#include <string>
#include <system_error>
#include <unordered_map>
#include <vector>

#include <benchmark/benchmark.h>

#include "collecting_reporter.h"

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/shapes.h"

#ifdef BISTURI_BENCH_OPENMESH
#include <OpenMesh/Core/Mesh/TriMesh_ArrayKernelT.hh>
#include <OpenMesh/Core/System/omstream.hh>
#endif

#ifdef BISTURI_BENCH_CGAL
#include <CGAL/Polygon_mesh_processing/orient_polygon_soup.h>
#include <CGAL/Polygon_mesh_processing/polygon_soup_to_polygon_mesh.h>
#include <CGAL/Polygon_mesh_processing/repair_polygon_soup.h>
#include <CGAL/Simple_cartesian.h>
#include <CGAL/Surface_mesh.h>
#endif

// ---- live and peak heap of C++ allocations (read only by the forked memory child) ----
//
// mallinfo2 says what is live, not the peak during a call. The program's own operator new /
// delete keep a running total of the usable bytes of every block while tracking is on.

namespace {
std::atomic<bool> g_tracking{false};
std::atomic<std::int64_t> g_live{0};
std::atomic<std::int64_t> g_peak{0};

void track_alloc(void* p) {
  const auto now = g_live.fetch_add(static_cast<std::int64_t>(malloc_usable_size(p)),
                                    std::memory_order_relaxed) +
                   static_cast<std::int64_t>(malloc_usable_size(p));
  std::int64_t peak = g_peak.load(std::memory_order_relaxed);
  while (now > peak && !g_peak.compare_exchange_weak(peak, now, std::memory_order_relaxed)) {
  }
}
}  // namespace

void* operator new(std::size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  if (g_tracking.load(std::memory_order_relaxed)) track_alloc(p);
  return p;
}
void operator delete(void* p) noexcept {
  if (p != nullptr && g_tracking.load(std::memory_order_relaxed)) {
    g_live.fetch_sub(static_cast<std::int64_t>(malloc_usable_size(p)), std::memory_order_relaxed);
  }
  std::free(p);
}
void operator delete(void* p, std::size_t /*size*/) noexcept {
  ::operator delete(p);
}

namespace {

using bisturi::ImportResult;
using bisturi::MeshFile;
using bisturi::MeshFormat;
using bisturi::PolygonMesh;

constexpr std::int64_t kSmall = 100'000;    // torus 500 x 100 x 2 triangles
constexpr std::int64_t kLarge = 2'000'000;  // torus 2000 x 500 x 2 triangles
constexpr int kLargeIterations = 2;

std::size_t heap_in_use() {
  const struct mallinfo2 info = mallinfo2();
  return info.uordblks + info.hblkhd;
}

// ---- the heap regime ----
//
// glibc moves its mmap threshold up after big blocks are freed, so whether a build's arrays come
// as fresh pages (page faults, expensive in this VM) or as recycled heap would depend on what ran
// before it: OpenMesh's unreserved build measured 4x faster after our runs than before them. Each
// run therefore pins one regime for every library and any order:
// - fresh (default): the threshold pinned to its default 128 KiB and, before every timed build,
//   malloc_trim(0), which hands every free page back to the kernel: each build's memory is fresh
//   (first touches fault), as in a process that builds its first mesh;
// - recycled: no mmap, no trimming, and a heap grown and touched up front, so every block is
//   memory the process has used before, as in a long-running process (page faults out).

enum class HeapMode { kFresh, kRecycled };
HeapMode g_heap_mode = HeapMode::kFresh;

/// Takes --heap=fresh|recycled out of argv (before Google Benchmark reads the rest).
std::optional<HeapMode> take_heap_flag(int& argc, char** argv) {
  HeapMode mode = HeapMode::kFresh;
  int kept = 1;
  for (int i = 1; i < argc; ++i) {
    const std::string arg = argv[i];
    if (arg.rfind("--heap=", 0) == 0) {
      if (arg == "--heap=fresh") {
        mode = HeapMode::kFresh;
      } else if (arg == "--heap=recycled") {
        mode = HeapMode::kRecycled;
      } else {
        return std::nullopt;
      }
      continue;
    }
    argv[kept++] = argv[i];
  }
  argc = kept;
  return mode;
}

void set_heap_mode(HeapMode mode) {
  g_heap_mode = mode;
  if (mode == HeapMode::kFresh) {
    mallopt(M_MMAP_THRESHOLD, 128 * 1024);
    return;
  }
  mallopt(M_MMAP_MAX, 0);
  mallopt(M_TRIM_THRESHOLD, std::numeric_limits<int>::max());
  // More than the inputs plus the largest build ever hold at once (about 1.5 GB at 2M
  // triangles), less than the trim threshold.
  constexpr std::size_t kPretouch = std::size_t{1900} << 20;
  if (void* p = std::malloc(kPretouch)) {
    // One write per page (a volatile one: malloc + memset 0 would become a calloc that
    // touches nothing).
    auto* bytes = static_cast<volatile unsigned char*>(p);
    for (std::size_t i = 0; i < kPretouch; i += 4096)
      bytes[i] = 1;
    std::free(p);
  }
}

/// Called before every timed build: in the fresh regime no free page stays resident.
void settle_heap() {
  if (g_heap_mode == HeapMode::kFresh) ::malloc_trim(0);
}

const char* heap_mode_line() {
  return g_heap_mode == HeapMode::kFresh
             ? "heap: fresh (malloc_trim before each build: its pages are new; --heap=recycled "
               "for a warmed heap)"
             : "heap: recycled (pre-touched heap, no mmap, no trim: page faults out; "
               "--heap=fresh for new pages)";
}

// ---- inputs: the torus as binary PLY and binary STL bytes, and as parsed arrays ----

PolygonMesh torus(std::int64_t triangles) {
  if (triangles == kSmall) return bisturi::torus_mesh(40.0, 12.0, 500, 100, true);
  if (triangles == kLarge) return bisturi::torus_mesh(40.0, 12.0, 2000, 500, true);
  const auto nv = static_cast<std::size_t>(std::lround(std::sqrt(double(triangles) / 8.0)));
  return bisturi::torus_mesh(40.0, 12.0, 4 * nv, nv, true);
}

/// The torus with holes: every 29th face removed unless it shares a vertex with one removed
/// before, so the surface stays manifold (every vertex one fan) with many triangular loops.
PolygonMesh holed(const PolygonMesh& closed, std::size_t& holes) {
  PolygonMesh out;
  out.positions = closed.positions;
  std::vector<char> used(closed.positions.size(), 0);
  holes = 0;
  for (std::size_t f = 0; f < closed.face_count(); ++f) {
    const auto t = closed.face(f);
    if (f % 29 == 0 && std::none_of(t.begin(), t.end(), [&](std::uint32_t v) { return used[v]; })) {
      for (const std::uint32_t v : t)
        used[v] = 1;
      ++holes;
      continue;
    }
    out.add_face(t);
  }
  return out;
}

void put_u32(std::vector<std::byte>& out, std::uint32_t v) {
  for (int i = 0; i < 4; ++i)
    out.push_back(static_cast<std::byte>((v >> (8 * i)) & 0xffu));
}
void put_f32(std::vector<std::byte>& out, double v) {
  put_u32(out, std::bit_cast<std::uint32_t>(static_cast<float>(v)));
}

/// Binary STL: 80-byte header, uint32 count, per triangle a normal and three corners (float32,
/// little-endian) and a uint16 attribute count.
std::vector<std::byte> stl_bytes(const PolygonMesh& mesh) {
  std::vector<std::byte> out(80, std::byte{' '});
  const char title[] = "bisturi import_bench torus";
  std::memcpy(out.data(), title, sizeof title - 1);
  out.reserve(84 + 50 * mesh.face_count());
  put_u32(out, static_cast<std::uint32_t>(mesh.face_count()));
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto t = mesh.face(f);
    const auto& a = mesh.positions[t[0]];
    const auto& b = mesh.positions[t[1]];
    const auto& c = mesh.positions[t[2]];
    const bisturi::Dlfl::Vec3 u = b - a, v = c - a;
    bisturi::Dlfl::Vec3 n(u.y * v.z - u.z * v.y, u.z * v.x - u.x * v.z, u.x * v.y - u.y * v.x);
    const double len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
    if (len > 0.0) n /= len;
    for (const auto& p : {n, a, b, c}) {
      put_f32(out, p.x);
      put_f32(out, p.y);
      put_f32(out, p.z);
    }
    out.push_back(std::byte{0});
    out.push_back(std::byte{0});
  }
  return out;
}

std::vector<std::byte> slurp(const std::filesystem::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::vector<char> chars((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  std::vector<std::byte> out(chars.size());
  std::memcpy(out.data(), chars.data(), chars.size());
  return out;
}

/// A temporary directory for the mesh files (each removed once read), removed at exit.
const std::filesystem::path& temp_dir() {
  struct Dir {
    std::filesystem::path path;
    Dir() {
      path = std::filesystem::temp_directory_path() /
             ("bisturi_import_bench." + std::to_string(::getpid()));
      std::filesystem::create_directories(path);
    }
    ~Dir() {
      std::error_code ec;
      std::filesystem::remove_all(path, ec);
    }
  };
  static const Dir dir;
  return dir.path;
}

#ifdef BISTURI_BENCH_CGAL
using CgalKernel = CGAL::Simple_cartesian<double>;
using CgalPoint = CgalKernel::Point_3;
using CgalMesh = CGAL::Surface_mesh<CgalPoint>;
using CgalTriangle = std::array<std::size_t, 3>;
namespace PMP = CGAL::Polygon_mesh_processing;

/// CGAL's soup types, filled from our arrays (off the clock: the same data in CGAL's form).
struct CgalSoup {
  std::vector<CgalPoint> points;
  std::vector<CgalTriangle> triangles;
};
CgalSoup cgal_soup(const PolygonMesh& mesh) {
  CgalSoup soup;
  soup.points.reserve(mesh.positions.size());
  for (const auto& p : mesh.positions)
    soup.points.emplace_back(p.x, p.y, p.z);
  soup.triangles.reserve(mesh.face_count());
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto t = mesh.face(f);
    soup.triangles.push_back({t[0], t[1], t[2]});
  }
  return soup;
}
#endif

struct Inputs {
  std::size_t triangles = 0;
  std::size_t vertices = 0;        // of the torus (what welding the soup must find)
  std::size_t open_triangles = 0;  // of the torus with holes
  std::size_t open_holes = 0;
  std::vector<std::byte> ply;
  std::vector<std::byte> stl;
  std::vector<std::byte> open_ply;
  MeshFile ply_file;  // parsed once: the arrays the peers build from
  MeshFile stl_file;
  MeshFile open_file;
#ifdef BISTURI_BENCH_CGAL
  std::optional<CgalSoup> cgal_indexed, cgal_soup, cgal_open;
#endif
};

Inputs& inputs(std::int64_t triangles) {
  static std::map<std::int64_t, std::unique_ptr<Inputs>> cache;
  auto& slot = cache[triangles];
  if (!slot) {
    slot = std::make_unique<Inputs>();
    Inputs& in = *slot;
    const std::string stem = "torus_" + std::to_string(triangles);
    {
      const PolygonMesh mesh = torus(triangles);
      in.triangles = mesh.face_count();
      in.vertices = mesh.positions.size();
      bisturi::write_ply(temp_dir() / (stem + ".ply"), mesh,
                         bisturi::PlyEncoding::BinaryLittleEndian);
      const std::vector<std::byte> stl = stl_bytes(mesh);
      std::ofstream(temp_dir() / (stem + ".stl"), std::ios::binary)
          .write(reinterpret_cast<const char*>(stl.data()),
                 static_cast<std::streamsize>(stl.size()));
      const PolygonMesh open = holed(mesh, in.open_holes);
      in.open_triangles = open.face_count();
      bisturi::write_ply(temp_dir() / (stem + "_open.ply"), open,
                         bisturi::PlyEncoding::BinaryLittleEndian);
    }
    in.ply = slurp(temp_dir() / (stem + ".ply"));
    in.stl = slurp(temp_dir() / (stem + ".stl"));
    in.open_ply = slurp(temp_dir() / (stem + "_open.ply"));
    std::filesystem::remove(temp_dir() / (stem + ".ply"));  // read once; nothing left behind
    std::filesystem::remove(temp_dir() / (stem + ".stl"));
    std::filesystem::remove(temp_dir() / (stem + "_open.ply"));
    in.ply_file = bisturi::read_mesh_from_memory(in.ply, MeshFormat::Ply, stem + ".ply");
    in.stl_file = bisturi::read_mesh_from_memory(in.stl, MeshFormat::Stl, stem + ".stl");
    in.open_file = bisturi::read_mesh_from_memory(in.open_ply, MeshFormat::Ply, stem + "_open.ply");
  }
  return *slot;
}

/// The closed torus as indexed PLY and as STL soup; the torus with holes as indexed PLY.
enum class Source { kPly, kStl, kOpenPly };

const std::vector<std::byte>& bytes_of(const Inputs& in, Source s) {
  return s == Source::kPly ? in.ply : s == Source::kStl ? in.stl : in.open_ply;
}
const MeshFile& file_of(const Inputs& in, Source s) {
  return s == Source::kPly ? in.ply_file : s == Source::kStl ? in.stl_file : in.open_file;
}
MeshFormat format_of(Source s) {
  return s == Source::kStl ? MeshFormat::Stl : MeshFormat::Ply;
}
std::size_t triangles_of(const Inputs& in, Source s) {
  return s == Source::kOpenPly ? in.open_triangles : in.triangles;
}

/// Minor page faults (first touches of fresh pages) inside the timed sections.
class FaultMeter {
 public:
  void resume() { start_ = now(); }
  void pause() { total_ += now() - start_; }
  [[nodiscard]] long total() const { return total_; }

 private:
  static long now() {
    struct rusage usage {};
    ::getrusage(RUSAGE_SELF, &usage);
    return usage.ru_minflt;
  }
  long start_ = 0;
  long total_ = 0;
};

/// Items are faces (items_per_second: faces per CPU second); page_faults per build.
void finish(benchmark::State& state, std::size_t triangles, const FaultMeter& faults) {
  state.counters["faces"] = double(triangles);
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(triangles));
  if (state.iterations() > 0) {
    state.counters["page_faults"] = double(faults.total()) / double(state.iterations());
  }
}

/// Everything our import promises for the torus: all faces kept, none dropped, the soup welded
/// back to the torus's vertices, one part of genus 1 (closed, or with one loop per hole).
std::optional<std::string> check_import(const bisturi::ImportReport& r, const Inputs& in,
                                        Source source) {
  if (r.faces != triangles_of(in, source) || !r.dropped.empty()) {
    return "import kept " + std::to_string(r.faces) + " of " +
           std::to_string(triangles_of(in, source)) + " faces";
  }
  if (r.vertices != in.vertices) {
    return "import has " + std::to_string(r.vertices) + " vertices, torus " +
           std::to_string(in.vertices);
  }
  const std::size_t loops = source == Source::kOpenPly ? in.open_holes : 0;
  if (r.parts.size() != 1 || r.parts[0].boundary_loops != loops || r.parts[0].genus != 1) {
    return "import: not one part of genus 1 with " + std::to_string(loops) + " boundary loops";
  }
  return std::nullopt;
}

// ---- bisturi: parse, construct, both ----

void BM_Parse(benchmark::State& state, Source source) {
  const Inputs& in = inputs(state.range(0));
  std::optional<MeshFile> file;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    file.emplace(bisturi::read_mesh_from_memory(bytes_of(in, source), format_of(source), "bench"));
    faults.pause();
    state.PauseTiming();
    if (file->polygons.face_count() != triangles_of(in, source)) {
      state.SkipWithError("parse: wrong face count");
      break;
    }
    file.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, triangles_of(in, source), faults);
  state.SetBytesProcessed(state.iterations() *
                          static_cast<std::int64_t>(bytes_of(in, source).size()));
}

void BM_Construct(benchmark::State& state, Source source) {
  const Inputs& in = inputs(state.range(0));
  const MeshFile& file = file_of(in, source);
  std::optional<ImportResult> result;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    result.emplace(bisturi::import_polygons(file.polygons, file.has_vertex_list));
    faults.pause();
    state.PauseTiming();
    if (const auto problem = check_import(result->report, in, source)) {
      state.SkipWithError(problem->c_str());
      break;
    }
    result.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, triangles_of(in, source), faults);
}

void BM_Total(benchmark::State& state, Source source) {
  const Inputs& in = inputs(state.range(0));
  std::optional<MeshFile> file;
  std::optional<ImportResult> result;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    file.emplace(bisturi::read_mesh_from_memory(bytes_of(in, source), format_of(source), "bench"));
    result.emplace(bisturi::import_polygons(file->polygons, file->has_vertex_list));
    faults.pause();
    state.PauseTiming();
    if (const auto problem = check_import(result->report, in, source)) {
      state.SkipWithError(problem->c_str());
      break;
    }
    result.reset();
    file.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, triangles_of(in, source), faults);
}

// ---- OpenMesh ----

#ifdef BISTURI_BENCH_OPENMESH
using TriMesh = OpenMesh::TriMesh_ArrayKernelT<>;

/// add_vertex for each vertex, add_face for each triangle; returns the faces refused.
std::size_t fill_openmesh(TriMesh& om, std::span<const bisturi::Dlfl::Vec3> positions,
                          std::span<const std::uint32_t> triangles, bool reserve) {
  const std::size_t nf = triangles.size() / 3;
  if (reserve) om.reserve(positions.size(), nf * 3 / 2 + 3, nf);
  std::vector<TriMesh::VertexHandle> handles;
  handles.reserve(positions.size());
  for (const auto& p : positions) {
    handles.push_back(om.add_vertex(
        TriMesh::Point(static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z))));
  }
  std::size_t rejected = 0;
  for (std::size_t f = 0; f < nf; ++f) {
    const auto fh = om.add_face(handles[triangles[3 * f]], handles[triangles[3 * f + 1]],
                                handles[triangles[3 * f + 2]]);
    if (!fh.is_valid()) ++rejected;
  }
  return rejected;
}

/// Exact weld of a soup with std::unordered_map (what a user of OpenMesh would write): unique
/// positions and the new index of every corner.
struct Welded {
  std::vector<bisturi::Dlfl::Vec3> positions;
  std::vector<std::uint32_t> triangles;
};
struct PointKey {
  std::uint64_t x, y, z;
  bool operator==(const PointKey&) const = default;
};
struct PointKeyHash {
  std::size_t operator()(const PointKey& k) const {
    std::uint64_t h = k.x * 0x9e3779b97f4a7c15ULL;
    h = (h ^ (h >> 29) ^ k.y) * 0xbf58476d1ce4e5b9ULL;
    h = (h ^ (h >> 32) ^ k.z) * 0x94d049bb133111ebULL;
    return static_cast<std::size_t>(h ^ (h >> 31));
  }
};
Welded weld_with_hash_map(const PolygonMesh& soup) {
  Welded out;
  std::unordered_map<PointKey, std::uint32_t, PointKeyHash> index;
  index.reserve(soup.positions.size() / 2);
  std::vector<std::uint32_t> new_index(soup.positions.size());
  for (std::size_t i = 0; i < soup.positions.size(); ++i) {
    const auto& p = soup.positions[i];
    // + 0.0 makes -0.0 into +0.0, so the two weld.
    const PointKey key{std::bit_cast<std::uint64_t>(p.x + 0.0),
                       std::bit_cast<std::uint64_t>(p.y + 0.0),
                       std::bit_cast<std::uint64_t>(p.z + 0.0)};
    const auto [it, inserted] =
        index.try_emplace(key, static_cast<std::uint32_t>(out.positions.size()));
    if (inserted) out.positions.push_back(p);
    new_index[i] = it->second;
  }
  out.triangles.reserve(soup.indices.size());
  for (const std::uint32_t i : soup.indices)
    out.triangles.push_back(new_index[i]);
  return out;
}

void BM_OpenMeshIndexed(benchmark::State& state, Source source, bool reserve) {
  const Inputs& in = inputs(state.range(0));
  const PolygonMesh& mesh = file_of(in, source).polygons;
  std::optional<TriMesh> om;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    om.emplace();
    const std::size_t rejected = fill_openmesh(*om, mesh.positions, mesh.indices, reserve);
    faults.pause();
    state.PauseTiming();
    if (rejected != 0) {
      state.SkipWithError("OpenMesh refused faces");
      break;
    }
    om.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, triangles_of(in, source), faults);
}

void BM_OpenMeshSoup(benchmark::State& state) {
  const Inputs& in = inputs(state.range(0));
  std::optional<TriMesh> om;
  std::optional<Welded> welded;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    welded.emplace(weld_with_hash_map(in.stl_file.polygons));
    om.emplace();
    const std::size_t rejected = fill_openmesh(*om, welded->positions, welded->triangles, false);
    faults.pause();
    state.PauseTiming();
    if (rejected != 0 || welded->positions.size() != in.vertices) {
      state.SkipWithError("OpenMesh soup: refused faces or wrong weld");
      break;
    }
    om.reset();
    welded.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, in.triangles, faults);
}
#endif  // BISTURI_BENCH_OPENMESH

// ---- CGAL ----

#ifdef BISTURI_BENCH_CGAL
const CgalSoup& cgal_input(Inputs& in, Source source) {
  auto& slot = source == Source::kPly   ? in.cgal_indexed
               : source == Source::kStl ? in.cgal_soup
                                        : in.cgal_open;
  if (!slot) slot.emplace(cgal_soup(file_of(in, source).polygons));
  return *slot;
}

/// polygon_soup_to_polygon_mesh from CGAL's arrays; `checked` adds the validity test
/// is_polygon_soup_a_polygon_mesh that the conversion requires of its input.
void BM_CgalIndexed(benchmark::State& state, Source source, bool checked) {
  Inputs& in = inputs(state.range(0));
  const CgalSoup& soup = cgal_input(in, source);
  if (!PMP::is_polygon_soup_a_polygon_mesh(soup.triangles)) {
    state.SkipWithError("CGAL: is_polygon_soup_a_polygon_mesh refused the torus");
    return;
  }
  std::optional<CgalMesh> sm;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    faults.resume();
    if (checked && !PMP::is_polygon_soup_a_polygon_mesh(soup.triangles)) {
      state.SkipWithError("CGAL: is_polygon_soup_a_polygon_mesh refused the torus");
      break;
    }
    sm.emplace();
    PMP::polygon_soup_to_polygon_mesh(soup.points, soup.triangles, *sm);
    faults.pause();
    state.PauseTiming();
    if (sm->number_of_faces() != triangles_of(in, source)) {
      state.SkipWithError("CGAL: wrong face count");
      break;
    }
    sm.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, triangles_of(in, source), faults);
}

/// merge_duplicate_points_in_polygon_soup, then polygon_soup_to_polygon_mesh (the soup is
/// copied off the clock: the merge works in place).
void BM_CgalSoup(benchmark::State& state) {
  Inputs& in = inputs(state.range(0));
  const CgalSoup& soup = cgal_input(in, Source::kStl);
  std::optional<CgalMesh> sm;
  std::optional<CgalSoup> work;
  FaultMeter faults;
  settle_heap();
  for (auto _ : state) {
    state.PauseTiming();
    work.emplace(soup);
    state.ResumeTiming();
    faults.resume();
    PMP::merge_duplicate_points_in_polygon_soup(work->points, work->triangles);
    sm.emplace();
    PMP::polygon_soup_to_polygon_mesh(work->points, work->triangles, *sm);
    faults.pause();
    state.PauseTiming();
    if (sm->number_of_faces() != in.triangles || sm->number_of_vertices() != in.vertices) {
      state.SkipWithError("CGAL soup: wrong face or vertex count");
      break;
    }
    sm.reset();
    work.reset();
    settle_heap();
    state.ResumeTiming();
  }
  finish(state, in.triangles, faults);
}
#endif  // BISTURI_BENCH_CGAL

// ---- non-manifold inputs: faces kept by each library ----

struct Case {
  std::string name;
  PolygonMesh mesh;
};

void add_tri(PolygonMesh& m, std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  m.add_face({a, b, c});
}

/// Quads and larger polygons as fans of triangles (OpenMesh's TriMesh and CGAL's arrays here
/// take triangles; the split is the same for all three libraries).
PolygonMesh triangulated(const PolygonMesh& in) {
  PolygonMesh out;
  out.positions = in.positions;
  for (std::size_t f = 0; f < in.face_count(); ++f) {
    const auto p = in.face(f);
    for (std::size_t k = 1; k + 1 < p.size(); ++k)
      add_tri(out, p[0], p[k], p[k + 1]);
  }
  return out;
}

/// Meshes joined into one, vertices at equal coordinates made one (a shared edge or vertex).
PolygonMesh joined(std::initializer_list<const PolygonMesh*> parts) {
  PolygonMesh out;
  std::map<std::array<double, 3>, std::uint32_t> at;
  for (const PolygonMesh* part : parts) {
    std::vector<std::uint32_t> index(part->positions.size());
    for (std::size_t v = 0; v < part->positions.size(); ++v) {
      const auto& p = part->positions[v];
      const auto [it, inserted] = at.try_emplace({p.x + 0.0, p.y + 0.0, p.z + 0.0},
                                                 static_cast<std::uint32_t>(out.positions.size()));
      if (inserted) out.positions.push_back(p);
      index[v] = it->second;
    }
    for (std::size_t f = 0; f < part->face_count(); ++f) {
      std::vector<std::uint32_t> face;
      for (const std::uint32_t i : part->face(f))
        face.push_back(index[i]);
      out.add_face(face);
    }
  }
  return out;
}

void flip(PolygonMesh& m, std::size_t f) {
  std::reverse(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
}

std::uint32_t add_point(PolygonMesh& m, double x, double y, double z) {
  m.positions.emplace_back(x, y, z);
  return static_cast<std::uint32_t>(m.positions.size() - 1);
}

PolygonMesh moebius(std::uint32_t n, double radius, double width) {
  PolygonMesh m;
  const double pi = std::acos(-1.0);
  for (std::uint32_t i = 0; i < n; ++i) {
    const double t = 2.0 * pi * double(i) / double(n);
    const double c = std::cos(t / 2.0) * width / 2.0, s = std::sin(t / 2.0) * width / 2.0;
    const double r0 = radius + c, r1 = radius - c;
    add_point(m, r0 * std::cos(t), r0 * std::sin(t), s);   // 2i: "top" edge
    add_point(m, r1 * std::cos(t), r1 * std::sin(t), -s);  // 2i + 1: "bottom" edge
  }
  for (std::uint32_t i = 0; i < n; ++i) {
    const std::uint32_t t0 = 2 * i, b0 = 2 * i + 1;
    // After a full turn the strip has turned half: top and bottom swap.
    const std::uint32_t t1 = i + 1 < n ? 2 * (i + 1) : 1;
    const std::uint32_t b1 = i + 1 < n ? 2 * (i + 1) + 1 : 0;
    add_tri(m, t0, b0, b1);
    add_tri(m, t0, b1, t1);
  }
  return m;
}

std::vector<Case> nonmanifold_cases() {
  std::vector<Case> cases;
  {
    const PolygonMesh a = bisturi::cube_mesh({0.0, 0.0, 0.0}, 1.0);
    const PolygonMesh b = bisturi::cube_mesh({1.0, 1.0, 0.0}, 1.0);
    cases.push_back({"two cubes sharing an edge", triangulated(joined({&a, &b}))});
  }
  {
    PolygonMesh m;
    add_point(m, 0, 0, 0);
    add_point(m, 0, 0, 1);
    for (int k = 0; k < 4; ++k) {
      const double t = 2.0 * std::acos(-1.0) * k / 4.0;
      add_tri(m, 0, 1, add_point(m, std::cos(t), std::sin(t), 0.5));
    }
    cases.push_back({"book: 4 triangles on one edge", std::move(m)});
  }
  {
    const PolygonMesh a = bisturi::tetrahedron_mesh();
    PolygonMesh b = a;  // point reflection through vertex 0, faces reversed to stay outward
    for (auto& p : b.positions)
      p = 2.0 * a.positions[0] - p;
    for (std::size_t f = 0; f < b.face_count(); ++f)
      flip(b, f);
    cases.push_back({"two tetrahedra sharing a vertex", joined({&a, &b})});
  }
  {
    PolygonMesh m;
    add_point(m, 0, 0, 0);
    add_point(m, 1, -0.5, 0);
    add_point(m, 1, 0.5, 0);
    add_point(m, -1, 0.5, 0);
    add_point(m, -1, -0.5, 0);
    add_tri(m, 0, 1, 2);
    add_tri(m, 0, 3, 4);
    cases.push_back({"bow-tie (2 triangles, 1 vertex)", std::move(m)});
  }
  {
    PolygonMesh m = bisturi::torus_mesh(40.0, 12.0, 20, 10, true);
    for (const std::size_t f : {0u, 57u, 123u, 250u, 399u}) {
      const auto face = m.face(f);
      add_tri(m, face[0], face[1], face[2]);
    }
    cases.push_back({"torus 400 + 5 duplicated faces", std::move(m)});
  }
  {
    PolygonMesh m = bisturi::torus_mesh(40.0, 12.0, 20, 10, true);
    for (std::size_t f = 5; f < m.face_count(); f += 10)
      flip(m, f);
    cases.push_back({"torus 400, 40 faces flipped", std::move(m)});
  }
  cases.push_back({"Moebius strip (48 triangles)", moebius(24, 10.0, 3.0)});
  {
    PolygonMesh m = bisturi::tetrahedron_mesh();
    const std::uint32_t a = add_point(m, 5, 0, 0), b = add_point(m, 6, 0, 0);
    const std::uint32_t c = add_point(m, 7, 0, 0);
    add_tri(m, a, b, c);  // collinear: zero area
    add_tri(m, 0, 0, 1);  // a vertex twice
    cases.push_back({"tetrahedron + 2 degenerate faces", std::move(m)});
  }
  {
    // 100k-triangle grid; 1% of its faces touched, 250 of each kind: duplicated, flipped, a fin
    // (a third face on an interior edge) and a fan (a second sheet at an interior vertex).
    PolygonMesh m = bisturi::grid_mesh(250, 200, 1.0, true);
    const std::size_t n = m.face_count();
    for (std::size_t k = 0; k < n / 100; ++k) {
      const std::size_t f = 100 * k + 50;
      const std::array<std::uint32_t, 3> t{m.face(f)[0], m.face(f)[1], m.face(f)[2]};
      const auto& p = m.positions[t[0]];
      const auto& q = m.positions[t[1]];
      switch (k % 4) {
        case 0:
          add_tri(m, t[0], t[1], t[2]);
          break;
        case 1:
          flip(m, f);
          break;
        case 2:
          add_tri(m, t[0], t[1],
                  add_point(m, (p.x + q.x) / 2, (p.y + q.y) / 2, 1.0));  // fin on edge t0-t1
          break;
        default: {
          const std::uint32_t u = add_point(m, p.x + 0.3, p.y + 0.1, 1.0);
          add_tri(m, t[0], u, add_point(m, p.x + 0.1, p.y + 0.3, 1.0));  // fan at t0
        }
      }
    }
    cases.push_back({"grid 100k, 1% dup/flip/fin/fan", std::move(m)});
  }
  return cases;
}

template <class... Args>
std::string format(const char* fmt, Args... args) {
  char buf[512];
  std::snprintf(buf, sizeof buf, fmt, args...);
  return buf;
}

void print_nonmanifold_table(std::ostream& out) {
#ifdef BISTURI_BENCH_OPENMESH
  omerr().disable();  // one "complex edge/vertex" line per refused face otherwise
#endif
  out << "\nNon-manifold inputs: faces kept (indexed input, no welding asked)\n"
      << format("  %-34s %7s | %-40s | %-13s | %s\n", "case", "faces", "bisturi import_polygons",
                "OpenMesh", "CGAL polygon_soup_to_polygon_mesh")
      << format("  %-34s %7s | %7s %4s %4s %4s %4s %4s %5s | %-13s |\n", "", "input", "kept",
                "drop", "nmE", "nmV", "flip", "seam", "valid", "add_face ref.");
  for (const Case& c : nonmanifold_cases()) {
    const std::size_t nf = c.mesh.face_count();
    std::string ours;
    try {
      const ImportResult r = bisturi::import_polygons(c.mesh, true);
      const bool valid = bisturi::validate(r.mesh).ok();
      std::size_t mapped = 0;
      for (const auto f : r.face_of_input)
        mapped += r.mesh.alive(f) ? 1 : 0;
      ours =
          format("%7zu %4zu %4zu %4zu %4zu %4zu %5s", r.report.faces, r.report.dropped.size(),
                 r.report.nonmanifold_edges, r.report.nonmanifold_vertices, r.report.flipped_faces,
                 r.report.seam_edges, valid && mapped == r.report.faces ? "yes" : "NO");
    } catch (const std::exception& e) {
      ours = std::string("threw: ") + e.what();
    }
    std::string om = "n/a";
#ifdef BISTURI_BENCH_OPENMESH
    {
      TriMesh mesh;
      const std::size_t rejected = fill_openmesh(mesh, c.mesh.positions, c.mesh.indices, false);
      om = format("%5zu refused", rejected);
    }
#endif
    std::string cgal = "n/a";
#ifdef BISTURI_BENCH_CGAL
    {
      CgalSoup soup = cgal_soup(c.mesh);
      if (PMP::is_polygon_soup_a_polygon_mesh(soup.triangles)) {
        CgalMesh sm;
        PMP::polygon_soup_to_polygon_mesh(soup.points, soup.triangles, sm);
        cgal = format("accepts (%zu faces)", sm.number_of_faces());
      } else {
        // The documented repair: orient_polygon_soup duplicates vertices (and may drop faces)
        // until the soup is an oriented manifold.
        const std::size_t points_before = soup.points.size();
        PMP::orient_polygon_soup(soup.points, soup.triangles);
        std::string after = "still refused";
        if (PMP::is_polygon_soup_a_polygon_mesh(soup.triangles)) {
          CgalMesh sm;
          PMP::polygon_soup_to_polygon_mesh(soup.points, soup.triangles, sm);
          after = format("then %zu faces", sm.number_of_faces());
        }
        cgal = format("refuses; orient_polygon_soup: +%zu vertices, %s",
                      soup.points.size() - points_before, after.c_str());
      }
    }
#endif
    out << format("  %-34s %7zu | %s | %-13s | %s\n", c.name.c_str(), nf, ours.c_str(), om.c_str(),
                  cgal.c_str());
  }
  out << "  kept/drop: faces in the DLFL and faces dropped as degenerate; nmE/nmV: non-manifold\n"
      << "  edges/vertices; flip: faces reversed to agree with neighbours; seam: edges cut to "
         "store\n"
      << "  a non-orientable part; valid: validate() clean and every kept input face mapped.\n";
}

// ---- peak memory of the 2M build, in a forked child ----

std::size_t proc_status_kb(const char* field) {
  std::ifstream in("/proc/self/status");
  std::string line;
  const std::size_t n = std::strlen(field);
  while (std::getline(in, line)) {
    if (line.compare(0, n, field) == 0) return std::strtoull(line.c_str() + n + 1, nullptr, 10);
  }
  return 0;
}

struct PeakMemory {
  bool ok = false;
  std::int64_t heap_peak = 0;                     // C++ heap, peak above the start (read + import)
  std::int64_t heap_after_parse = 0;              // the MeshFile
  std::int64_t heap_end = 0;                      // MeshFile + ImportResult
  std::size_t mallinfo_end = 0;                   // mallinfo2 growth, MeshFile + ImportResult
  std::size_t dlfl_bytes = 0;                     // memory_bytes() of the DLFL
  std::size_t rss_start_kb = 0, rss_peak_kb = 0;  // VmRSS at start, VmHWM after (reset)
  long maxrss_kb = 0;                             // getrusage ru_maxrss (not reset)
};

PeakMemory measure_in_child(const std::vector<std::byte>& bytes, MeshFormat format) {
  PeakMemory result;
  int fds[2];
  if (::pipe(fds) != 0) return result;
  std::fflush(nullptr);
  const pid_t pid = ::fork();
  if (pid < 0) return result;
  if (pid == 0) {
    ::close(fds[0]);
    PeakMemory m;
    ::malloc_trim(0);  // memory freed before the fork goes back to the system: re-use shows
    std::ofstream("/proc/self/clear_refs") << "5";  // resets VmHWM to the current VmRSS
    m.rss_start_kb = proc_status_kb("VmRSS:");
    const std::size_t mallinfo_start = heap_in_use();
    g_live = 0;
    g_peak = 0;
    g_tracking = true;
    try {
      auto file = std::make_unique<MeshFile>(bisturi::read_mesh_from_memory(bytes, format, "mem"));
      m.heap_after_parse = g_live.load();
      auto imported = std::make_unique<ImportResult>(
          bisturi::import_polygons(file->polygons, file->has_vertex_list));
      m.heap_end = g_live.load();
      m.heap_peak = g_peak.load();
      g_tracking = false;
      m.mallinfo_end = heap_in_use() - mallinfo_start;
      m.dlfl_bytes = imported->mesh.memory_bytes();
      m.rss_peak_kb = proc_status_kb("VmHWM:");
      struct rusage usage {};
      ::getrusage(RUSAGE_SELF, &usage);
      m.maxrss_kb = usage.ru_maxrss;
      m.ok = true;
    } catch (...) {
      m.ok = false;
    }
    const ssize_t written = ::write(fds[1], &m, sizeof m);
    ::_exit(written == static_cast<ssize_t>(sizeof m) ? 0 : 1);
  }
  ::close(fds[1]);
  const ssize_t got = ::read(fds[0], &result, sizeof result);
  ::close(fds[0]);
  int status = 0;
  ::waitpid(pid, &status, 0);
  if (got != static_cast<ssize_t>(sizeof result)) result.ok = false;
  return result;
}

void print_peak_memory(std::ostream& out) {
  const Inputs& in = inputs(kLarge);
  out << format("\nPeak memory, bisturi read_mesh_from_memory + import_polygons, %zu triangles\n",
                in.triangles)
      << "  (forked child; file bytes already in memory and not counted; arrays of 1 MiB and\n"
      << "   more come from posix_memalign (BigVector), so only RSS and mallinfo2 see them)\n";
  const double mb = 1024.0 * 1024.0;
  const auto tri = double(in.triangles);
  for (const Source s : {Source::kPly, Source::kStl, Source::kOpenPly}) {
    const PeakMemory m = measure_in_child(bytes_of(in, s), format_of(s));
    const char* label = s == Source::kPly   ? "indexed PLY"
                        : s == Source::kStl ? "STL soup"
                                            : "open PLY";
    if (!m.ok) {
      out << "  " << label << ": the child failed\n";
      continue;
    }
    const double rss = double(m.rss_peak_kb - m.rss_start_kb) * 1024.0;
    out << format("  %-11s (%.1f MB file)\n", label, double(bytes_of(in, s).size()) / mb)
        << format("    peak operator-new heap (small blocks) %7.1f MB  %6.1f bytes/triangle\n",
                  double(m.heap_peak) / mb, double(m.heap_peak) / tri)
        << format("    peak RSS growth (VmHWM - VmRSS)      %8.1f MB  %6.1f bytes/triangle\n",
                  rss / mb, rss / tri)
        << format("    operator-new heap after parse         %7.1f MB  %6.1f bytes/triangle\n",
                  double(m.heap_after_parse) / mb, double(m.heap_after_parse) / tri)
        << format("    operator-new heap at the end         %8.1f MB  (mallinfo2: %.1f MB)\n",
                  double(m.heap_end) / mb, double(m.mallinfo_end) / mb)
        << format("    final DLFL memory_bytes()            %8.1f MB  %6.1f bytes/triangle\n",
                  double(m.dlfl_bytes) / mb, double(m.dlfl_bytes) / tri)
        << format("    ru_maxrss of the child (whole process, inherited pages included) %.1f MB\n",
                  double(m.maxrss_kb) / 1024.0);
  }
}

// ---- summary ----

using bisturi::bench::CollectingReporter;

/// Faces per CPU second (or wall second) of the run `name/<size>`.
std::optional<double> rate(const CollectingReporter& runs, const std::string& name,
                           std::int64_t size, bool wall) {
  const auto* run = runs.find(name + "/" + std::to_string(size));
  if (run == nullptr) return std::nullopt;
  const double t = wall ? run->GetAdjustedRealTime() : run->GetAdjustedCPUTime();
  const double s = t / benchmark::GetTimeUnitMultiplier(run->time_unit);
  return s > 0.0 ? std::optional<double>(double(size) / s) : std::nullopt;
}

std::string mps(std::optional<double> v) {
  return v ? format("%6.2f", *v / 1e6) : "     -";
}
std::string ratio(std::optional<double> a, std::optional<double> b) {
  return a && b ? format("%5.2fx", *a / *b) : "    -";
}

struct Peer {
  const char* key;
  const char* label;
  const char* ours;  // our run on the same input
};
constexpr Peer kPeers[] = {
    {"openmesh/indexed", "OpenMesh TriMesh, indexed", "bisturi/indexed_ply"},
    {"openmesh/indexed_reserved", "OpenMesh TriMesh, indexed, reserve(V,E,F)",
     "bisturi/indexed_ply"},
    {"openmesh/soup_unordered_map_weld", "OpenMesh TriMesh, soup + unordered_map weld",
     "bisturi/stl_soup"},
    {"cgal/indexed", "CGAL Surface_mesh, indexed", "bisturi/indexed_ply"},
    {"cgal/indexed_checked", "CGAL, indexed + is_polygon_soup_a_polygon_mesh",
     "bisturi/indexed_ply"},
    {"cgal/soup_merge_duplicate_points", "CGAL, soup + merge_duplicate_points", "bisturi/stl_soup"},
    {"openmesh/open", "OpenMesh TriMesh, torus with holes", "bisturi/open_ply"},
    {"cgal/open", "CGAL Surface_mesh, torus with holes", "bisturi/open_ply"},
};

/// Throughput and ratio tables, per CPU second or per wall second.
void print_rates(const CollectingReporter& runs, std::ostream& out, bool wall) {
  auto r_rate = [&](const std::string& name, std::int64_t size) {
    return rate(runs, name, size, wall);
  };
  out << format("  %-47s %21s   %21s\n", wall ? "per WALL second" : "per CPU second",
                "100k triangles", "2M triangles")
      << format("  %-47s %6s %7s %6s   %6s %7s %6s\n", "", "parse", "constr", "total", "parse",
                "constr", "total");
  const struct {
    const char* key;
    const char* label;
  } ours[] = {{"bisturi/indexed_ply", "bisturi, indexed binary PLY"},
              {"bisturi/stl_soup", "bisturi, binary STL soup (welded)"},
              {"bisturi/open_ply", "bisturi, torus with holes, indexed PLY"}};
  for (const auto& o : ours) {
    const std::string k = o.key;
    out << format(
        "  %-47s %s  %s  %s   %s  %s  %s\n", o.label, mps(r_rate(k + "/parse", kSmall)).c_str(),
        mps(r_rate(k + "/construct", kSmall)).c_str(), mps(r_rate(k + "/total", kSmall)).c_str(),
        mps(r_rate(k + "/parse", kLarge)).c_str(), mps(r_rate(k + "/construct", kLarge)).c_str(),
        mps(r_rate(k + "/total", kLarge)).c_str());
  }
  std::string rows;
  for (const Peer& p : kPeers) {
    const auto s = r_rate(p.key, kSmall), l = r_rate(p.key, kLarge);
    if (!s && !l) continue;
    out << format("  %-47s %6s  %s  %6s   %6s  %s  %6s\n", p.label, "", mps(s).c_str(), "", "",
                  mps(l).c_str(), "");
    const std::string o = p.ours;
    rows += format("  %-47s %7s %7s     %7s %7s\n", p.label,
                   ratio(r_rate(o + "/construct", kSmall), s).c_str(),
                   ratio(r_rate(o + "/total", kSmall), s).c_str(),
                   ratio(r_rate(o + "/construct", kLarge), l).c_str(),
                   ratio(r_rate(o + "/total", kLarge), l).c_str());
  }
  if (rows.empty()) {
    if (!wall) {
      out << "  (no peers: configure with -DBISTURI_BENCH_OPENMESH=ON -DBISTURI_BENCH_CGAL=ON)\n";
    }
    return;
  }
  out << format("  bisturi / peer, %s (> 1: bisturi faster; goal >= 1x CGAL, >= 3x OpenMesh)\n",
                wall ? "wall" : "CPU")
      << format("  %-47s %15s     %15s\n", "", "100k triangles", "2M triangles")
      << format("  %-47s %7s %7s     %7s %7s\n", "peer", "constr", "total", "constr", "total")
      << rows;
}

void print_summary(CollectingReporter& r) {
  std::ostream& out = r.summary_stream();
  out << "\nSummary: build throughput in million triangles per second. File bytes already in\n"
      << "memory; input copies and destruction not timed. bisturi: parse = read_mesh_from_memory,\n"
      << "constr = import_polygons, total = both in one timed section. The peers build from the\n"
      << "parsed arrays (no parse): compare them with constr (like for like) and with total (ours\n"
      << "paying the parse too).\n";
  out << "  " << heap_mode_line() << "\n";
  print_rates(r, out, false);
  out << "\n";
  print_rates(r, out, true);
}

void register_benchmarks() {
  using benchmark::RegisterBenchmark;
  auto sizes = [](benchmark::internal::Benchmark* b, std::int64_t size) {
    b->Arg(size)->Unit(benchmark::kMillisecond);
    if (size == kLarge) b->Iterations(kLargeIterations);
  };
  // The 100k runs first, then the 2M runs, so that each size's inputs are made once.
  for (const std::int64_t size : {kSmall, kLarge}) {
    for (const Source s : {Source::kPly, Source::kStl}) {
      const std::string key = s == Source::kPly ? "bisturi/indexed_ply" : "bisturi/stl_soup";
      sizes(RegisterBenchmark((key + "/parse").c_str(), BM_Parse, s), size);
      sizes(RegisterBenchmark((key + "/construct").c_str(), BM_Construct, s), size);
      sizes(RegisterBenchmark((key + "/total").c_str(), BM_Total, s), size);
    }
    // The torus with holes: construction only (its parse is the indexed PLY's).
    sizes(RegisterBenchmark("bisturi/open_ply/construct", BM_Construct, Source::kOpenPly), size);
#ifdef BISTURI_BENCH_OPENMESH
    sizes(RegisterBenchmark("openmesh/indexed", BM_OpenMeshIndexed, Source::kPly, false), size);
    sizes(RegisterBenchmark("openmesh/indexed_reserved", BM_OpenMeshIndexed, Source::kPly, true),
          size);
    sizes(RegisterBenchmark("openmesh/soup_unordered_map_weld", BM_OpenMeshSoup), size);
    sizes(RegisterBenchmark("openmesh/open", BM_OpenMeshIndexed, Source::kOpenPly, false), size);
#endif
#ifdef BISTURI_BENCH_CGAL
    sizes(RegisterBenchmark("cgal/indexed", BM_CgalIndexed, Source::kPly, false), size);
    sizes(RegisterBenchmark("cgal/indexed_checked", BM_CgalIndexed, Source::kPly, true), size);
    sizes(RegisterBenchmark("cgal/soup_merge_duplicate_points", BM_CgalSoup), size);
    sizes(RegisterBenchmark("cgal/open", BM_CgalIndexed, Source::kOpenPly, false), size);
#endif
  }
}

/// The 100k imports once more, checked with validate() (too slow to do inside the timing).
bool check_small_imports(std::ostream& out) {
  const Inputs& in = inputs(kSmall);
  bool ok = true;
  for (const Source s : {Source::kPly, Source::kStl, Source::kOpenPly}) {
    const MeshFile& file = file_of(in, s);
    const ImportResult r = bisturi::import_polygons(file.polygons, file.has_vertex_list);
    const bisturi::ValidationReport v = bisturi::validate(r.mesh);
    const auto problem = check_import(r.report, in, s);
    out << format(
        "  check %s %zu triangles: %zu faces, %zu vertices (%zu welded), %zu dropped, "
        "genus %lld, %zu boundary loops, validate() %s\n",
        s == Source::kPly   ? "indexed PLY"
        : s == Source::kStl ? "STL soup"
                            : "open PLY",
        triangles_of(in, s), r.report.faces, r.report.vertices, r.report.welded_vertices,
        r.report.dropped.size(),
        static_cast<long long>(r.report.parts.empty() ? -1 : r.report.parts[0].genus.value_or(-1)),
        r.report.parts.empty() ? std::size_t{0} : r.report.parts[0].boundary_loops,
        v.ok() ? "ok" : "BROKEN");
    if (problem) out << "    " << *problem << "\n";
    if (!v.ok()) out << v.summary() << "\n";
    ok = ok && v.ok() && !problem;
  }
  return ok;
}

}  // namespace

int main(int argc, char** argv) {
  const std::optional<HeapMode> heap = take_heap_flag(argc, argv);
  if (!heap) {
    std::fprintf(stderr, "import_bench: --heap takes fresh or recycled\n");
    return 1;
  }
  set_heap_mode(*heap);
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;
  register_benchmarks();
  CollectingReporter reporter;
  benchmark::RunSpecifiedBenchmarks(&reporter);
  std::ostream& out = reporter.summary_stream();
  print_summary(reporter);
  print_nonmanifold_table(out);
  print_peak_memory(out);
  out << "\n";
  const bool ok = check_small_imports(out);
  out.flush();
  benchmark::Shutdown();
  return ok ? 0 : 1;
}
