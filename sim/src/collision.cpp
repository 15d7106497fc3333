#include "bisturi/sim/collision.h"

#include <embree3/rtcore.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <limits>
#include <mutex>
#include <string>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"
#include "bvh_patches.h"

namespace bisturi::sim {

CollisionDevice::CollisionDevice(unsigned threads) {
  const std::string config = threads == 0 ? std::string() : "threads=" + std::to_string(threads);
  RTCDevice d = rtcNewDevice(config.c_str());
  if (d == nullptr) throw CollisionError("embree: rtcNewDevice failed");
  device_ = d;
}

CollisionDevice::~CollisionDevice() {
  rtcReleaseDevice(static_cast<RTCDevice>(device_));
}

glm::dvec3 closest_point_on_segment(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                    double& t) {
  const glm::dvec3 ab = b - a;
  const double length2 = glm::dot(ab, ab);
  t = length2 > 0.0 ? std::clamp(glm::dot(p - a, ab) / length2, 0.0, 1.0) : 0.0;
  return a + t * ab;
}

namespace {

/// A triangle without area (its corners on one line, or two of them one point): the closest
/// point on its three sides. The region tests below would divide by zero there.
glm::dvec3 closest_on_flat_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                    const glm::dvec3& c, glm::dvec3& bc) {
  double t = 0.0;
  glm::dvec3 best = closest_point_on_segment(p, a, b, t);
  bc = {1 - t, t, 0};
  const glm::dvec3 on_bc = closest_point_on_segment(p, b, c, t);
  if (glm::length(p - on_bc) < glm::length(p - best)) best = on_bc, bc = {0, 1 - t, t};
  const glm::dvec3 on_ca = closest_point_on_segment(p, c, a, t);
  if (glm::length(p - on_ca) < glm::length(p - best)) best = on_ca, bc = {t, 0, 1 - t};
  return best;
}

}  // namespace

glm::dvec3 closest_point_on_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                     const glm::dvec3& c, glm::dvec3& bc) {
  // Ericson, Real-Time Collision Detection, 5.1.5 (region tests on the barycentric coordinates).
  const glm::dvec3 ab = b - a, ac = c - a, ap = p - a;
  const double d1 = glm::dot(ab, ap), d2 = glm::dot(ac, ap);
  if (d1 <= 0.0 && d2 <= 0.0) return bc = {1, 0, 0}, a;
  const glm::dvec3 bp = p - b;
  const double d3 = glm::dot(ab, bp), d4 = glm::dot(ac, bp);
  if (d3 >= 0.0 && d4 <= d3) return bc = {0, 1, 0}, b;
  const double vc = d1 * d4 - d3 * d2;
  // Each division below is by zero only on a triangle without area: then its sides answer.
  if (vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0) {
    if (d1 == d3) return closest_on_flat_triangle(p, a, b, c, bc);
    const double v = d1 / (d1 - d3);
    bc = {1 - v, v, 0};
    return a + v * ab;
  }
  const glm::dvec3 cp = p - c;
  const double d5 = glm::dot(ab, cp), d6 = glm::dot(ac, cp);
  if (d6 >= 0.0 && d5 <= d6) return bc = {0, 0, 1}, c;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0) {
    if (d2 == d6) return closest_on_flat_triangle(p, a, b, c, bc);
    const double w = d2 / (d2 - d6);
    bc = {1 - w, 0, w};
    return a + w * ac;
  }
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0) {
    if (d4 - d3 + d5 - d6 == 0.0) return closest_on_flat_triangle(p, a, b, c, bc);
    const double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    bc = {0, 1 - w, w};
    return b + w * (c - b);
  }
  if (!(va + vb + vc > 0.0)) return closest_on_flat_triangle(p, a, b, c, bc);
  const double denom = 1.0 / (va + vb + vc);
  const double v = vb * denom, w = vc * denom;
  bc = {1 - v - w, v, w};
  return a + ab * v + ac * w;
}

/// One patch's Embree geometry (a triangle mesh over the shared vertex buffer), the body's
/// triangle behind each primitive (Embree's primID -> an index into the body's SurfaceTriangles,
/// kDeadTriangle for a primitive kept after a cut that no triangle has now) and the corners
/// Embree holds.
struct PatchGeometry {
  RTCScene scene = nullptr;        // the patch's own BVH (owned here)
  RTCGeometry geometry = nullptr;  // its triangles (owned by its scene)
  RTCGeometry instance = nullptr;  // its instance in the top level (owned by the top scene)
  std::vector<std::uint32_t> triangles;
  std::vector<std::uint32_t> corners;
};

struct SurfaceBvh::Impl {
  PatchRebuildLimits limits;
  RTCDevice device = nullptr;
  RTCScene scene = nullptr;
  /// Instance ID in the top scene = index. The last one is the loose patch: the triangles that
  /// a cut made in patches kept stale (it is rebuilt on each topology change, and small).
  std::vector<PatchGeometry> patches;
  SurfacePatches patch_map;
  std::vector<float> vertices;  // shared by every patch; capacity for a cut's new vertices
  std::size_t vertex_capacity = 0;
  RTCScene user_scene = nullptr;  // for rtcCollide
  RTCGeometry user_geometry = nullptr;
  unsigned user_count = 0;         // its primitives
  const SoftBody* body = nullptr;  // for the bounds callback during a commit only
  double margin = 0.0;
  std::uint64_t version = 0;
  std::uint64_t rebuilds = 0, refits = 0;
  std::size_t last_rebuilt_patches = 0, last_refitted_patches = 0;
  std::vector<std::uint32_t> indices;  // copy of the body's triangles at the last build
  /// The patches whose primitives use each vertex, from the corners Embree holds (a dead
  /// primitive's bounds are in its patch's BVH too): the first one per vertex (patches.size(),
  /// a slot no patch reads, for none) and the further ones of the few vertices on a border as
  /// (vertex, patch) pairs, sorted. Per block of kBlock vertices, its first pair and the
  /// patches its vertices use (block b's are block_patches[block_first[b] ..
  /// block_first[b + 1])). A refit commits the patches marked in patch_moved.
  std::vector<std::uint32_t> vertex_patch;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> more_patches;
  std::vector<std::uint32_t> block_more, block_first, block_patches;
  std::vector<std::uint8_t> patch_moved;  // by patch, and the slot for none
  /// Lazy refits: a patch is refitted once the most its vertices may have moved since its last
  /// refit (drift, a bound summed from each update's largest move among them) exceeds the
  /// tolerance. The queries widen their radius by the largest drift left (query_pad), which keeps
  /// them exact: a triangle now at distance d lies in stale bounds within d + drift.
  double refit_tolerance = 0.0;
  std::vector<double> drift;       // by patch, and the slot for none
  std::vector<float> update_move;  // by patch: this update's largest move of one of its vertices
  double query_pad = 0.0;
  std::vector<std::uint32_t> index_scratch;  // of index_vertex_patches
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pair_scratch;

  ~Impl() { release(); }
  void release() {
    release_user();
    if (scene) rtcReleaseScene(scene);
    scene = nullptr;
    for (PatchGeometry& g : patches)
      if (g.scene) rtcReleaseScene(g.scene);
    patches.clear();
  }
  void release_user() {
    if (user_scene) rtcReleaseScene(user_scene);
    user_scene = nullptr;
    user_geometry = nullptr;
    user_count = 0;
  }

  /// The body's triangle behind Embree's (instance ID, primID); kDeadTriangle for none.
  [[nodiscard]] std::uint32_t triangle_of(unsigned geom, unsigned prim) const {
    return patches[geom].triangles[prim];
  }

  /// Embree's intersection filter: a ray passes through dead primitives.
  static void skip_dead(const RTCFilterFunctionNArguments* args) {
    const auto* self = static_cast<const Impl*>(args->geometryUserPtr);
    for (unsigned i = 0; i < args->N; ++i) {
      if (args->valid[i] == 0) continue;
      const unsigned inst = RTCHitN_instID(args->hit, args->N, i, 0);
      const unsigned prim = RTCHitN_primID(args->hit, args->N, i);
      if (self->triangle_of(inst, prim) == kDeadTriangle) args->valid[i] = 0;
    }
  }

  void fill_vertices(const SoftBody& b) {
    const auto& x = b.positions();
    for (std::size_t i = 0; i < x.size(); ++i) {
      vertices[3 * i] = static_cast<float>(x[i].x);
      vertices[3 * i + 1] = static_cast<float>(x[i].y);
      vertices[3 * i + 2] = static_cast<float>(x[i].z);
    }
  }

  /// Gives patch p's corners to Embree (a new index buffer; an empty patch is disabled).
  void set_corners(std::size_t p, std::vector<std::uint32_t> corners) {
    PatchGeometry& g = patches[p];
    g.corners = std::move(corners);
    const std::size_t nt = g.corners.size() / 3;
    if (nt == 0) {
      rtcDisableGeometry(g.instance);
      return;
    }
    rtcEnableGeometry(g.instance);
    auto* ib = static_cast<unsigned*>(rtcSetNewGeometryBuffer(
        g.geometry, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, 3 * sizeof(unsigned), nt));
    std::copy(g.corners.begin(), g.corners.end(), ib);
  }

  [[nodiscard]] std::vector<std::uint32_t> corners_of(
      const std::vector<std::uint32_t>& triangles) const {
    std::vector<std::uint32_t> c(3 * triangles.size());
    for (std::size_t k = 0; k < triangles.size(); ++k)
      for (std::size_t j = 0; j < 3; ++j)
        c[3 * k + j] = indices[3 * std::size_t{triangles[k]} + j];
    return c;
  }

  static constexpr std::size_t kBlock = 64;  // vertices compared at a time
  using BlockDiff = std::array<std::uint32_t, 3 * kBlock>;
  using BlockMove = std::array<float, kBlock>;  // per vertex, its largest coordinate change

  /// Indexes the patches of each vertex and block (after the patches' corners changed).
  /// Patches are visited in order, so a vertex's first patch is its smallest, and a repeat of a
  /// (vertex, further patch) pair can only follow its first within the same patch. Linear
  /// passes (stamps and a counting sort by block): sorting the pairs cost most of a millisecond
  /// of a cut's preparation at 20k vertices.
  void index_vertex_patches() {
    const auto none = static_cast<std::uint32_t>(patches.size());
    vertex_patch.assign(vertex_capacity, none);
    // Scratch kept between calls: fresh pages cost more than these passes on this project's VM.
    std::vector<std::uint32_t>& last_more = index_scratch;
    std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs = pair_scratch;
    last_more.assign(vertex_capacity, none);
    pairs.clear();
    for (std::uint32_t p = 0; p < patches.size(); ++p) {
      for (const std::uint32_t v : patches[p].corners) {
        if (vertex_patch[v] == none) {
          vertex_patch[v] = p;
        } else if (vertex_patch[v] != p && last_more[v] != p) {
          last_more[v] = p;
          pairs.emplace_back(v, p);
        }
      }
    }
    // The pairs grouped by block (block_more offsets into more_patches).
    const std::size_t blocks = (vertex_capacity + kBlock - 1) / kBlock;
    block_more.assign(blocks + 1, 0);
    for (const auto& [v, p] : pairs)
      ++block_more[v / kBlock + 1];
    for (std::size_t b = 0; b < blocks; ++b)
      block_more[b + 1] += block_more[b];
    more_patches.resize(pairs.size());
    std::vector<std::uint32_t>& fill = index_scratch;  // last_more is done with
    fill.assign(block_more.begin(), block_more.end() - 1);
    for (const auto& pair : pairs)
      more_patches[fill[pair.first / kBlock]++] = pair;
    index_blocks();
    patch_moved.assign(patches.size() + 1, 0);
  }

  /// The patches each block's vertices use. A block whose patches are all marked already needs
  /// no look at each vertex: when every vertex moves, that is most blocks (neighbouring blocks
  /// lie in the same few patches).
  void index_blocks() {
    const std::size_t blocks = (vertex_capacity + kBlock - 1) / kBlock;
    const auto none = static_cast<std::uint32_t>(patches.size());
    std::vector<std::size_t> stamp(patches.size(), blocks);  // the block that listed it
    block_first.assign(1, 0);
    block_patches.clear();
    auto list = [&](std::size_t b, std::uint32_t p) {
      if (p == none || stamp[p] == b) return;  // none: nothing to refit for the vertex
      stamp[p] = b;
      block_patches.push_back(p);
    };
    for (std::size_t b = 0; b < blocks; ++b) {
      const std::size_t first = b * kBlock, last = std::min(first + kBlock, vertex_capacity);
      for (std::size_t v = first; v < last; ++v)
        list(b, vertex_patch[v]);
      for (std::uint32_t e = block_more[b]; e < block_more[b + 1]; ++e)
        list(b, more_patches[e].second);
      block_first.push_back(static_cast<std::uint32_t>(block_patches.size()));
    }
  }

  /// Copies n positions into the float buffer at v, with the bits that changed in `diff`, and
  /// each vertex's largest coordinate change in `move`; returns whether any bit changed. The
  /// first pass has no branch, so that it vectorises (compared per vertex with a branch, the
  /// pass cost 3.5 times the bare copy; this way, twice); the moves are measured only in a
  /// block that changed.
  static bool copy_block(const glm::dvec3* x, std::size_t n, float* v, BlockDiff& diff,
                         BlockMove& move) {
    std::array<float, 3 * kBlock> fresh;
    for (std::size_t k = 0; k < n; ++k) {
      const float f[3] = {static_cast<float>(x[k].x), static_cast<float>(x[k].y),
                          static_cast<float>(x[k].z)};
      for (std::size_t c = 0; c < 3; ++c) {
        diff[3 * k + c] =
            std::bit_cast<std::uint32_t>(f[c]) ^ std::bit_cast<std::uint32_t>(v[3 * k + c]);
        fresh[3 * k + c] = f[c];
      }
    }
    std::uint32_t any = 0;
    for (std::size_t j = 0; j < 3 * n; ++j)
      any |= diff[j];
    if (any == 0) return false;  // most blocks, most steps: the bare copy's cost
    // A NaN coordinate, old or new, counts as an infinite move: its patches refit at once.
    constexpr float kInfinity = std::numeric_limits<float>::infinity();
    for (std::size_t k = 0; k < n; ++k) {
      float m = 0.0f;
      for (std::size_t c = 0; c < 3; ++c) {
        const float d = std::abs(fresh[3 * k + c] - v[3 * k + c]);
        m = std::isnan(d) ? kInfinity : std::max(m, d);
        v[3 * k + c] = fresh[3 * k + c];
      }
      move[k] = m;
    }
    return true;
  }

  /// Notes this update's largest move per patch from block b's vertices (n of them).
  void mark_block(std::size_t b, std::size_t n, const BlockMove& move) {
    float* most = update_move.data();
    const std::uint32_t* used = block_patches.data() + block_first[b];
    const std::uint32_t used_count = block_first[b + 1] - block_first[b];
    if (used_count == 1) {  // every vertex of the block in one patch
      most[used[0]] = std::max(most[used[0]], *std::max_element(move.begin(), move.begin() + n));
      return;
    }
    const std::uint32_t* patch = &vertex_patch[b * kBlock];
    for (std::size_t k = 0; k < n; ++k)
      most[patch[k]] = std::max(most[patch[k]], move[k]);
    for (std::uint32_t e = block_more[b]; e < block_more[b + 1]; ++e) {
      const std::uint32_t p = more_patches[e].second;
      most[p] = std::max(most[p], move[more_patches[e].first - b * kBlock]);
    }
  }

  /// Copies the body's positions into the float buffer like fill_vertices, and adds each
  /// patch's largest move (of a vertex whose float triple changed) to its drift; patch_moved
  /// marks the patches with a move.
  void fill_moved_vertices(const SoftBody& b) {
    BlockDiff diff{};
    BlockMove move{};
    const auto& x = b.positions();
    update_move.assign(patches.size() + 1, 0.0f);
    for (std::size_t first = 0; first < x.size(); first += kBlock) {
      const std::size_t n = std::min(kBlock, x.size() - first);
      if (copy_block(&x[first], n, &vertices[3 * first], diff, move))
        mark_block(first / kBlock, n, move);
    }
    drift.resize(patches.size() + 1, 0.0);
    // patch_moved: moved since the patch's last refit. The largest coordinate change times
    // sqrt(3) bounds the distance moved.
    for (std::size_t p = 0; p < patches.size(); ++p) {
      if (update_move[p] > 0.0f || patch_moved[p] != 0) {
        patch_moved[p] = 1;
        drift[p] += double(update_move[p]) * 1.7320508075688772;
      }
    }
  }

  /// Marks the patch's vertices as changed and commits its geometry and scene (Embree refits a
  /// patch it did not rebuild) and its instance (the top level takes the patch's new bounds).
  void commit_patch(PatchGeometry& g) {
    rtcUpdateGeometryBuffer(g.geometry, RTC_BUFFER_TYPE_VERTEX, 0);
    rtcCommitGeometry(g.geometry);
    rtcCommitScene(g.scene);
    rtcCommitGeometry(g.instance);
  }

  void commit_top() {
    rtcCommitScene(scene);
    if (rtcGetDeviceError(device) != RTC_ERROR_NONE) throw CollisionError("embree: build failed");
  }

  /// Commits every non-empty patch and the top level over them.
  void commit_all() {
    last_refitted_patches = 0;
    for (PatchGeometry& g : patches) {
      if (g.corners.empty()) continue;
      commit_patch(g);
      ++last_refitted_patches;
    }
    commit_top();
    drift.assign(patches.size() + 1, 0.0);
    query_pad = 0.0;
  }

  /// The refit: commits the patches a vertex of which moved, and the top level when one did
  /// (when nothing moved, every BVH still fits).
  void refit(const SoftBody& b) {
    fill_moved_vertices(b);
    commit_drifted(refit_tolerance);
  }

  /// Refits the moved patches whose drift exceeds `tolerance`; the others wait, and the queries
  /// widen by the largest drift left.
  void commit_drifted(double tolerance) {
    last_refitted_patches = 0;
    query_pad = 0.0;
    for (std::size_t p = 0; p < patches.size(); ++p) {
      if (patch_moved[p] == 0) continue;
      if (drift[p] <= tolerance && tolerance > 0.0) {
        query_pad = std::max(query_pad, drift[p]);
        continue;
      }
      patch_moved[p] = 0;
      drift[p] = 0.0;
      commit_patch(patches[p]);
      ++last_refitted_patches;
    }
    if (last_refitted_patches > 0) commit_top();
  }

  void build(const SoftBody& b) {
    release();
    scene = rtcNewScene(device);
    // COMPACT keeps indexed triangles in the leaves instead of copies of their vertices: a refit
    // then only recomputes bounds (19.4k-vertex sphere, Zen 1: 0.43-0.49 ms against 0.75-1.2 ms).
    // The top level holds one identity instance per patch; each patch's scene is refitted or
    // rebuilt on its own (see bvh_patches.h).
    rtcSetSceneFlags(scene,
                     RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_COMPACT | RTC_SCENE_FLAG_ROBUST);
    rtcSetSceneBuildQuality(scene, RTC_BUILD_QUALITY_LOW);
    indices = b.triangles().indices;
    patch_map.assign(b.triangles(), b.positions());
    // Room for the vertices of a few cuts; Embree reads the last vertex with a 16-byte load.
    const std::size_t nv = b.positions().size();
    vertex_capacity = nv + nv / 4 + 64;
    vertices.assign(3 * vertex_capacity + 1, 0.0f);
    fill_vertices(b);
    std::vector<std::vector<std::uint32_t>> split = patch_map.split(b.triangles());
    split.emplace_back();  // the loose patch, empty
    patches.resize(split.size());
    static constexpr float kIdentity[12] = {1, 0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0};
    for (std::size_t p = 0; p < split.size(); ++p) {
      RTCScene ps = rtcNewScene(device);
      rtcSetSceneFlags(ps, RTC_SCENE_FLAG_DYNAMIC | RTC_SCENE_FLAG_COMPACT | RTC_SCENE_FLAG_ROBUST);
      rtcSetSceneBuildQuality(ps, RTC_BUILD_QUALITY_LOW);
      RTCGeometry g = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_TRIANGLE);
      rtcSetGeometryBuildQuality(g, RTC_BUILD_QUALITY_REFIT);
      rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, vertices.data(),
                                 0, 3 * sizeof(float), vertex_capacity);
      rtcSetGeometryUserData(g, this);
      rtcSetGeometryIntersectFilterFunction(g, &Impl::skip_dead);
      rtcSetGeometryOccludedFilterFunction(g, &Impl::skip_dead);
      rtcAttachGeometryByID(ps, g, 0);
      rtcReleaseGeometry(g);  // the patch's scene holds it
      RTCGeometry inst = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_INSTANCE);
      rtcSetGeometryInstancedScene(inst, ps);
      rtcSetGeometryTransform(inst, 0, RTC_FORMAT_FLOAT3X4_COLUMN_MAJOR, kIdentity);
      rtcAttachGeometryByID(scene, inst, static_cast<unsigned>(p));
      rtcReleaseGeometry(inst);  // the top scene holds it
      patches[p].scene = ps;
      patches[p].geometry = g;
      patches[p].instance = inst;
      patches[p].triangles = std::move(split[p]);
      set_corners(p, corners_of(patches[p].triangles));
    }
    index_vertex_patches();
    commit_all();
    version = b.topology_version();
    last_rebuilt_patches = patches.size();
    ++rebuilds;
  }

  /// Gives patch p the triangles `home` with their `corners` (a rebuild when they change).
  void rebuild_patch(std::size_t p, std::vector<std::uint32_t> home,
                     std::vector<std::uint32_t> corners) {
    patches[p].triangles = std::move(home);
    if (corners == patches[p].corners) return;
    set_corners(p, std::move(corners));
    ++last_rebuilt_patches;
  }

  /// After a topology change. A patch whose triangles did not change is refitted. One that did
  /// keeps its BVH when few of its primitives died or were added (a cut changes a few hundred
  /// triangles; rebuilding a patch of 4096 costs about 2 ms): its dead primitives are skipped by
  /// the queries and its new triangles go to the loose patch. Otherwise, and for every stale
  /// patch once the loose patch is full, the patch is rebuilt. A full build when the new
  /// vertices do not fit the shared buffer.
  void rebuild_changed(const SoftBody& b) {
    // A body that had no triangles has no patches to keep.
    if (scene == nullptr || patches.size() < 2 || b.positions().size() > vertex_capacity) {
      build(b);
      return;
    }
    indices = b.triangles().indices;  // the user geometry's count is set at its next commit
    patch_map.assign_new_faces(b.triangles(), b.positions());
    std::vector<std::vector<std::uint32_t>> split = patch_map.split(b.triangles());
    fill_vertices(b);
    last_rebuilt_patches = 0;
    std::vector<std::uint32_t> loose, prim_triangle;
    std::vector<std::size_t> stale;
    for (std::size_t p = 0; p < split.size(); ++p) {
      PatchGeometry& g = patches[p];
      std::vector<std::uint32_t> corners = corners_of(split[p]);
      if (corners == g.corners) {
        g.triangles = std::move(split[p]);
        continue;
      }
      std::vector<std::uint32_t> added =
          match_primitives(g.corners, split[p], indices, prim_triangle);
      const auto dead = static_cast<std::size_t>(
          std::count(prim_triangle.begin(), prim_triangle.end(), kDeadTriangle));
      if (g.corners.empty() ||
          double(dead + added.size()) > limits.stale_share * double(prim_triangle.size())) {
        rebuild_patch(p, std::move(split[p]), std::move(corners));
        continue;
      }
      g.triangles = prim_triangle;
      loose.insert(loose.end(), added.begin(), added.end());
      stale.push_back(p);
    }
    if (loose.size() > limits.loose_triangles) {
      for (const std::size_t p : stale)
        rebuild_patch(p, split[p], corners_of(split[p]));
      loose.clear();
    }
    std::sort(loose.begin(), loose.end());
    std::vector<std::uint32_t> loose_corners = corners_of(loose);
    rebuild_patch(patches.size() - 1, std::move(loose), std::move(loose_corners));
    index_vertex_patches();
    commit_all();
    version = b.topology_version();
    ++rebuilds;
  }

  static void bounds(const RTCBoundsFunctionArguments* args) {
    const auto* self = static_cast<const Impl*>(args->geometryUserPtr);
    const auto& x = self->body->positions();
    const std::uint32_t* t = &self->indices[3 * std::size_t{args->primID}];
    glm::dvec3 lo = x[t[0]], hi = x[t[0]];
    for (int k = 1; k < 3; ++k) {
      lo = glm::min(lo, x[t[k]]);
      hi = glm::max(hi, x[t[k]]);
    }
    lo -= glm::dvec3(self->margin);
    hi += glm::dvec3(self->margin);
    RTCBounds* o = args->bounds_o;
    o->lower_x = static_cast<float>(lo.x);
    o->lower_y = static_cast<float>(lo.y);
    o->lower_z = static_cast<float>(lo.z);
    o->upper_x = static_cast<float>(hi.x);
    o->upper_y = static_cast<float>(hi.y);
    o->upper_z = static_cast<float>(hi.z);
  }

  void commit_user(const SoftBody& b, double m) {
    body = &b;
    margin = m;
    if (user_scene == nullptr) {
      user_scene = rtcNewScene(device);
      rtcSetSceneFlags(user_scene, RTC_SCENE_FLAG_DYNAMIC);
      rtcSetSceneBuildQuality(user_scene, RTC_BUILD_QUALITY_LOW);
      user_geometry = rtcNewGeometry(device, RTC_GEOMETRY_TYPE_USER);
      rtcSetGeometryBuildQuality(user_geometry, RTC_BUILD_QUALITY_REFIT);
      rtcSetGeometryUserData(user_geometry, this);
      rtcSetGeometryBoundsFunction(user_geometry, &Impl::bounds, this);
      rtcAttachGeometry(user_scene, user_geometry);
      rtcReleaseGeometry(user_geometry);
    }
    const auto count = static_cast<unsigned>(indices.size() / 3);
    // A cut changed the count: the same scene builds again (its memory reused), not a new one.
    if (user_count != count) rtcSetGeometryUserPrimitiveCount(user_geometry, count);
    user_count = count;
    rtcCommitGeometry(user_geometry);
    rtcCommitScene(user_scene);
    body = nullptr;
  }
};

SurfaceBvh::SurfaceBvh(const CollisionDevice& device, const SoftBody& body)
    : impl_(std::make_unique<Impl>()) {
  impl_->device = static_cast<RTCDevice>(device.handle());
  rtcRetainDevice(impl_->device);
  impl_->build(body);
}

SurfaceBvh::~SurfaceBvh() {
  if (impl_) {
    RTCDevice d = impl_->device;
    impl_.reset();
    rtcReleaseDevice(d);
  }
}
SurfaceBvh::SurfaceBvh(SurfaceBvh&&) noexcept = default;
SurfaceBvh& SurfaceBvh::operator=(SurfaceBvh&&) noexcept = default;

void SurfaceBvh::update(const SoftBody& body) {
  // Vertex slots past the shared buffer (slots made without a topology change) need a build.
  if (body.topology_version() != impl_->version ||
      impl_->indices.size() != body.triangles().indices.size() ||
      body.positions().size() > impl_->vertex_capacity) {
    impl_->rebuild_changed(body);
    return;
  }
  impl_->refit(body);
  ++impl_->refits;
}

std::uint64_t SurfaceBvh::rebuilds() const {
  return impl_->rebuilds;
}
std::uint64_t SurfaceBvh::refits() const {
  return impl_->refits;
}
std::size_t SurfaceBvh::patch_count() const {
  return impl_->patches.size();
}
std::size_t SurfaceBvh::last_rebuilt_patches() const {
  return impl_->last_rebuilt_patches;
}
std::size_t SurfaceBvh::last_refitted_patches() const {
  return impl_->last_refitted_patches;
}
std::size_t SurfaceBvh::loose_triangles() const {
  return impl_->patches.empty() ? 0 : impl_->patches.back().triangles.size();
}
void SurfaceBvh::set_rebuild_limits(const PatchRebuildLimits& limits) {
  impl_->limits = limits;
}
void SurfaceBvh::set_refit_tolerance(double drift_m) {
  impl_->refit_tolerance = std::max(drift_m, 0.0);
}

namespace {

/// The closest point to p on the body's triangle behind a point query's hit (triangle =
/// kDeadTriangle and no point for a dead primitive).
struct HitPoint {
  std::uint32_t triangle;
  glm::dvec3 point;
  glm::dvec3 barycentric;
};
HitPoint closest_on_hit(const SurfaceBvh::Impl& bvh, const SoftBody& body,
                        const RTCPointQueryFunctionArguments* args, const glm::dvec3& p) {
  HitPoint h{bvh.triangle_of(args->context->instID[0], args->primID), {}, {}};
  if (h.triangle == kDeadTriangle) return h;
  const std::uint32_t* t = &bvh.indices[3 * std::size_t{h.triangle}];
  const auto& x = body.positions();
  h.point = closest_point_on_triangle(p, x[t[0]], x[t[1]], x[t[2]], h.barycentric);
  return h;
}

struct PointQueryData {
  const SoftBody* body;
  const SurfaceBvh::Impl* bvh;
  glm::dvec3 p;
  double limit;  ///< the caller's max distance
  float pad;     ///< the BVH's query_pad: how far stale bounds may lag
  SurfacePoint best;
};

bool point_query(RTCPointQueryFunctionArguments* args) {
  auto* d = static_cast<PointQueryData*>(args->userPtr);
  const HitPoint h = closest_on_hit(*d->bvh, *d->body, args, d->p);
  if (h.triangle == kDeadTriangle) return false;
  const double dist = glm::length(h.point - d->p);
  const bool better = !d->best.found || dist < d->best.distance_m ||
                      (dist == d->best.distance_m && h.triangle < d->best.triangle);
  if (!better || dist > d->limit) return false;
  d->best.found = true;
  d->best.point_m = h.point;
  d->best.distance_m = dist;
  d->best.triangle = h.triangle;
  d->best.barycentric = h.barycentric;
  args->query->radius = static_cast<float>(dist) * 1.0001f + 1e-9f + d->pad;
  return true;
}

glm::dvec3 triangle_normal(const SoftBody& body, const std::vector<std::uint32_t>& idx,
                           std::uint32_t triangle) {
  const auto& x = body.positions();
  const std::size_t t = 3 * std::size_t{triangle};
  const glm::dvec3 n = glm::cross(x[idx[t + 1]] - x[idx[t]], x[idx[t + 2]] - x[idx[t]]);
  const double l = glm::length(n);
  return l > 0.0 ? n / l : glm::dvec3(0.0, 0.0, 1.0);
}

}  // namespace

SurfacePoint SurfaceBvh::closest_point(const SoftBody& body, const glm::dvec3& p,
                                       double max_distance_m) const {
  const auto pad = static_cast<float>(impl_->query_pad);
  PointQueryData data{&body, impl_.get(), p, max_distance_m, pad, {}};
  RTCPointQuery q;
  q.x = static_cast<float>(p.x);
  q.y = static_cast<float>(p.y);
  q.z = static_cast<float>(p.z);
  q.time = 0.0f;
  q.radius = static_cast<float>(std::min(max_distance_m, 1e30)) * 1.0001f + pad;
  RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(impl_->scene, &q, &ctx, &point_query, &data);
  if (data.best.found) {
    data.best.normal =
        body.orientation() * triangle_normal(body, impl_->indices, data.best.triangle);
  }
  return data.best;
}

namespace {

struct NearQueryData {
  const SoftBody* body;
  const SurfaceBvh::Impl* bvh;
  glm::dvec3 p;
  double radius;
  std::vector<std::uint32_t>* found;
};

bool near_query(RTCPointQueryFunctionArguments* args) {
  auto* d = static_cast<NearQueryData*>(args->userPtr);
  const HitPoint h = closest_on_hit(*d->bvh, *d->body, args, d->p);
  if (h.triangle == kDeadTriangle) return false;
  if (glm::length(h.point - d->p) <= d->radius) d->found->push_back(h.triangle);
  return false;  // keep the radius: every triangle within it is wanted
}

}  // namespace

std::vector<std::uint32_t> SurfaceBvh::triangles_near(const SoftBody& body, const glm::dvec3& p,
                                                      double radius_m) const {
  std::vector<std::uint32_t> found;
  triangles_near(body, p, radius_m, found);
  return found;
}

void SurfaceBvh::triangles_near(const SoftBody& body, const glm::dvec3& p, double radius_m,
                                std::vector<std::uint32_t>& found) const {
  found.clear();
  NearQueryData data{&body, impl_.get(), p, radius_m, &found};
  RTCPointQuery q;
  q.x = static_cast<float>(p.x);
  q.y = static_cast<float>(p.y);
  q.z = static_cast<float>(p.z);
  q.time = 0.0f;
  q.radius = static_cast<float>(radius_m) * 1.0001f + 1e-9f + static_cast<float>(impl_->query_pad);
  RTCPointQueryContext ctx;
  rtcInitPointQueryContext(&ctx);
  rtcPointQuery(impl_->scene, &q, &ctx, &near_query, &data);
  std::sort(found.begin(), found.end());
  found.erase(std::unique(found.begin(), found.end()), found.end());
}

SurfacePoint SurfaceBvh::ray(const SoftBody& body, const glm::dvec3& from,
                             const glm::dvec3& to) const {
  SurfacePoint out;
  const glm::dvec3 d = to - from;
  const double len = glm::length(d);
  if (!(len > 0.0)) return out;
  // Embree tests rays against the float vertices, which stale bounds may no longer hold: the
  // waiting refits first (rays are rare: the scalpel's).
  impl_->commit_drifted(0.0);
  RTCRayHit rh{};
  rh.ray.org_x = static_cast<float>(from.x);
  rh.ray.org_y = static_cast<float>(from.y);
  rh.ray.org_z = static_cast<float>(from.z);
  rh.ray.dir_x = static_cast<float>(d.x / len);
  rh.ray.dir_y = static_cast<float>(d.y / len);
  rh.ray.dir_z = static_cast<float>(d.z / len);
  rh.ray.tnear = 0.0f;
  rh.ray.tfar = static_cast<float>(len);
  rh.ray.mask = 0xFFFFFFFFu;
  rh.ray.flags = 0;
  rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
  RTCIntersectContext ctx;
  rtcInitIntersectContext(&ctx);
  rtcIntersect1(impl_->scene, &ctx, &rh);
  if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return out;
  out.found = true;
  out.triangle = impl_->triangle_of(rh.hit.instID[0], rh.hit.primID);
  out.distance_m = rh.ray.tfar;
  out.barycentric = {1.0 - rh.hit.u - rh.hit.v, rh.hit.u, rh.hit.v};
  const auto& x = body.positions();
  const std::uint32_t* t = &impl_->indices[3 * std::size_t{out.triangle}];
  out.point_m =
      out.barycentric.x * x[t[0]] + out.barycentric.y * x[t[1]] + out.barycentric.z * x[t[2]];
  out.normal = body.orientation() * triangle_normal(body, impl_->indices, out.triangle);
  return out;
}

std::pair<glm::dvec3, glm::dvec3> SurfaceBvh::bounds() const {
  RTCBounds b;
  rtcGetSceneBounds(impl_->scene, &b);
  const double pad = impl_->query_pad;
  return {glm::dvec3(b.lower_x, b.lower_y, b.lower_z) - pad,
          glm::dvec3(b.upper_x, b.upper_y, b.upper_z) + pad};
}

namespace {
struct CollideData {
  std::mutex mutex;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
};
void collide(void* user, RTCCollision* collisions, unsigned count) {
  auto* d = static_cast<CollideData*>(user);
  std::lock_guard<std::mutex> lock(d->mutex);
  for (unsigned i = 0; i < count; ++i)
    d->pairs.emplace_back(collisions[i].primID0, collisions[i].primID1);
}
}  // namespace

std::vector<std::pair<std::uint32_t, std::uint32_t>> SurfaceBvh::overlapping_triangles(
    const SoftBody& body, SurfaceBvh& other, const SoftBody& other_body, double margin_m) {
  impl_->commit_user(body, margin_m);
  other.impl_->commit_user(other_body, margin_m);
  CollideData data;
  rtcCollide(impl_->user_scene, other.impl_->user_scene, &collide, &data);
  // Embree may call back from several threads: sort for one deterministic order.
  std::sort(data.pairs.begin(), data.pairs.end());
  data.pairs.erase(std::unique(data.pairs.begin(), data.pairs.end()), data.pairs.end());
  return std::move(data.pairs);
}

}  // namespace bisturi::sim
