#pragma once
// Internal: the fast path of import_polygons() for the common input, closed surfaces oriented
// consistently: every edge in exactly two faces that run it in opposite directions, and the
// faces around every vertex one fan (no bow-tie). For such input the general path (orient, the
// rotation system, the bulk assembler) flips nothing, adds no hole and gives every vertex one
// rotation, so its DLFL follows from the polygons alone: after one lone point sphere per unused
// vertex (k of them, in vertex order, as create_vertex makes them), side h is corner k + h,
// polygon f is face k + f, edges come in the order of their first side and rotations in the order
// of their vertex's first side. This writes those arrays once, in place (RawArrays, like marching
// cubes), with the report's topology figures, and gives up on anything else: the Dlfl is then
// emptied and the positions handed back, for the general path.

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/polygon_import.h"
#include "raw_arrays.h"

namespace bisturi::construction {

namespace closed_manifold_detail {

/// Marks a union-find root that already has its part number (in the low bits).
inline constexpr std::uint32_t kPartTag = 0x80000000u;

/// The vertex cycle of a face from its smallest vertex, in the direction whose second vertex is
/// smaller (a face and its reverse, from any start, read alike); as import_report.cpp compares.
template <class CornerVertex>
void canonical_cycle(const CornerVertex& vertex_of, std::uint32_t begin, std::uint32_t n,
                     std::vector<std::uint32_t>& out) {
  std::uint32_t m = 0;
  for (std::uint32_t i = 1; i < n; ++i) {
    if (vertex_of(begin + i) < vertex_of(begin + m)) m = i;
  }
  const bool forward = vertex_of(begin + (m + 1) % n) <= vertex_of(begin + (m + n - 1) % n);
  out.clear();
  for (std::uint32_t i = 0; i < n; ++i)
    out.push_back(vertex_of(begin + (forward ? (m + i) % n : (m + n - i) % n)));
}

}  // namespace closed_manifold_detail

/// `vertex_of(h)`: the (welded) vertex of side h of the kept polygons; `offsets`: CSR over them.
/// On success the Dlfl holds the mesh (it must be empty before), `positions` is moved into it
/// and the topology fields of `report` are set (vertices, isolated_vertices, edges, faces,
/// nonmanifold_*, flipped_faces, seam_edges, duplicate_faces, parts).
template <class CornerVertex>
bool write_closed_manifold(Dlfl& d, const CornerVertex& vertex_of,
                           std::span<const std::uint32_t> offsets, BigVector<Dlfl::Vec3>& positions,
                           ImportReport& report) {
  using namespace closed_manifold_detail;
  const std::size_t nv = positions.size();
  const std::size_t nf = offsets.size() - 1;
  const std::size_t nh = offsets[nf];
  // Odd side counts cannot pair up; the tag bit must stay free for part numbers.
  if (nh % 2 != 0 || nh >= kPartTag || nv >= kPartTag || nf == 0) return false;

  // Which vertices the polygons use; the others become lone point spheres (k of them). `head`
  // later starts each vertex's list of leaving sides, linked through the corners' prev fields
  // (prev is written last), so the lists cost no memory of their own.
  constexpr std::uint32_t kUnused = 0xffffffffu;
  constexpr std::uint32_t kEndOfList = 0xfffffffeu;
  ScratchVector<std::uint32_t> head(nv, kUnused);
  for (std::uint32_t h = 0; h < nh; ++h)
    head[vertex_of(h)] = kEndOfList;
  const auto k = static_cast<std::uint32_t>(std::count(head.begin(), head.end(), kUnused));

  const RawArrays::View w =
      RawArrays::size_empty(d, std::move(positions), nh + k, nf + k, nf + k, nh / 2);
  auto give_up = [&] {
    positions = std::move(d.positions());
    d = Dlfl();
    return false;
  };

  // Point spheres first, numbered in vertex order (corner, face and rotation alike).
  {
    std::uint32_t s = 0;
    for (std::uint32_t v = 0; v < nv; ++v) {
      if (head[v] != kUnused) continue;
      w.corners[s] = {VertexId(v), FaceId(s), CornerId(s), CornerId(s), EdgeId{}};
      w.faces[s].first = CornerId(s);
      w.rotations[s].corner = CornerId(s);
      w.vertices[v].first = RotationId(s);
      ++s;
    }
  }

  // Corners and faces; a vertex's rotation is numbered (and anchored) at its first side.
  Dlfl::CornerRecord* const corners = w.corners + k;  // indexed by side
  std::uint32_t rotation = k;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t e = offsets[f + 1];
    w.faces[k + f].first = CornerId(k + b);
    for (std::uint32_t h = b; h < e; ++h) {
      const std::uint32_t v = vertex_of(h);
      const std::uint32_t next = h + 1 == e ? b : h + 1;
      corners[h] = {VertexId(v), FaceId(k + f), CornerId(k + next), CornerId(head[v]), EdgeId{}};
      head[v] = h;
      if (!w.vertices[v].first.valid()) {
        w.vertices[v].first = RotationId(rotation);
        w.rotations[rotation++].corner = CornerId(k + h);
      }
    }
  }

  // Twins: side h (a -> b) pairs with the one side b -> a. None (a boundary), several, or one
  // already paired (an edge in three or more faces, or run twice one way) leaves the fast path.
  // Parts are joined across every edge on the way (vertex union-find, roots later tagged).
  ScratchVector<std::uint32_t> parent(nv);
  for (std::uint32_t v = 0; v < nv; ++v)
    parent[v] = v;
  auto root = [&](std::uint32_t x) {
    while (parent[x] != x) {
      parent[x] = parent[parent[x]];
      x = parent[x];
    }
    return x;
  };
  auto head_vertex = [&](std::uint32_t h) { return corners[corners[h].next.idx - k].vertex.idx; };
  std::uint32_t edge_count = 0;
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (corners[h].edge.valid()) continue;
    const std::uint32_t a = corners[h].vertex.idx;
    const std::uint32_t b = head_vertex(h);
    std::uint32_t twin = kEndOfList;
    std::uint32_t matches = 0;
    for (std::uint32_t x = head[b]; x != kEndOfList; x = corners[x].prev.idx) {
      if (head_vertex(x) == a) {
        twin = x;
        ++matches;
      }
    }
    if (matches != 1 || corners[twin].edge.valid()) return give_up();
    const EdgeId edge(edge_count++);
    w.edges[edge.idx] = {CornerId(k + h), CornerId(k + twin)};
    corners[h].edge = edge;
    corners[twin].edge = edge;
    const std::uint32_t ra = root(a);
    const std::uint32_t rb = root(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  // The lists are done with: prev takes its meaning.
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t e = offsets[f + 1];
    corners[b].prev = CornerId(k + e - 1);
    for (std::uint32_t h = b + 1; h < e; ++h)
      corners[h].prev = CornerId(k + h - 1);
  }

  // One fan per vertex: every side lies on one rotation cycle (x -> twin(prev(x))), so the
  // cycles through the vertices' first sides cover all sides exactly when no vertex has a
  // second fan (a bow-tie).
  auto twin_corner = [&](std::uint32_t c) {
    const CornerPair& p = w.edges[w.corners[c].edge.idx];
    return p.a.idx == c ? p.b.idx : p.a.idx;
  };
  std::size_t covered = 0;
  for (std::uint32_t r = k; r < rotation; ++r) {
    const std::uint32_t first = w.rotations[r].corner.idx;
    std::uint32_t x = first;
    do {
      x = twin_corner(w.corners[x].prev.idx);
      ++covered;
    } while (x != first && covered <= nh);
  }
  if (covered != nh) return give_up();

  // Parts in the order of their first face, as the orientation walk numbers them. Roots get
  // their part number tagged in; a path step onto a tagged root copies the tag.
  auto part_of = [&](std::uint32_t x) -> std::uint32_t {
    while (true) {
      const std::uint32_t p = parent[x];
      if ((p & kPartTag) != 0) return p;
      if (p == x) return x;
      const std::uint32_t pp = parent[p];
      if ((pp & kPartTag) != 0) return pp;
      parent[x] = pp;
      x = pp;
    }
  };
  std::vector<ImportPart> parts;
  std::size_t duplicates = 0;
  std::vector<std::uint32_t> mine, theirs;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t n = offsets[f + 1] - b;
    const std::uint32_t r = part_of(corners[b].vertex.idx);
    std::uint32_t part = r & ~kPartTag;
    if ((r & kPartTag) == 0) {
      part = static_cast<std::uint32_t>(parts.size());
      parts.emplace_back();
      parent[r] = kPartTag | part;
    }
    ++parts[part].faces;
    parts[part].edges += n;  // sides for now: two per edge
    // Duplicates: a face with the cycle of an earlier one shares its first side's edge with it.
    const std::uint32_t g = w.corners[twin_corner(k + b)].face.idx - k;
    if (g >= f || offsets[g + 1] - offsets[g] != n) continue;
    const std::uint32_t og = offsets[g];
    bool all_in = true;  // cheap reject first: a duplicate holds every vertex of the face
    for (std::uint32_t i = 0; i < n && n <= 16 && all_in; ++i) {
      bool found = false;
      for (std::uint32_t j = 0; j < n && !found; ++j)
        found = corners[b + i].vertex == corners[og + j].vertex;
      all_in = found;
    }
    if (!all_in) continue;
    if (n == 3) {  // three distinct vertices: every order is a turn or the reverse of the face
      ++duplicates;
      continue;
    }
    auto vertex_at = [&](std::uint32_t h) { return corners[h].vertex.idx; };
    canonical_cycle(vertex_at, b, n, mine);
    canonical_cycle(vertex_at, og, n, theirs);
    duplicates += mine == theirs ? 1 : 0;
  }
  for (std::uint32_t v = 0; v < nv; ++v) {
    if (head[v] != kUnused) ++parts[part_of(v) & ~kPartTag].vertices;
  }
  for (ImportPart& part : parts) {
    part.edges /= 2;
    part.closed = true;
    part.boundary_loops = 0;
    part.orientable = true;
    part.euler = static_cast<std::int64_t>(part.vertices) - static_cast<std::int64_t>(part.edges) +
                 static_cast<std::int64_t>(part.faces);
    part.genus = (2 - part.euler - static_cast<std::int64_t>(part.boundary_loops)) / 2;
  }

  RawArrays::finish(d, std::size_t{k} + 1);  // create_vertex per sphere, then the bulk write
  report.vertices = nv - k;
  report.isolated_vertices = k;
  report.edges = nh / 2;
  report.faces = nf;
  report.nonmanifold_edges = 0;
  report.nonmanifold_vertices = 0;
  report.flipped_faces = 0;
  report.seam_edges = 0;
  report.duplicate_faces = duplicates;
  report.parts = std::move(parts);
  return true;
}

}  // namespace bisturi::construction
