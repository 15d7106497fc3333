#pragma once
// Internal: the fast path of import_polygons() for the common input, consistently oriented
// manifold surfaces, closed or with boundary: every edge in one face or in two that run it in
// opposite directions, and the faces around every vertex one fan (no bow-tie). For such input the
// general path (orient, the rotation system, the bulk assembler) flips nothing and gives every
// vertex one rotation, so its DLFL follows from the polygons alone: after one lone point sphere
// per unused vertex (k of them, in vertex order, as create_vertex makes them), side h is corner
// k + h, polygon f is face k + f, edges come in the order of their first side and rotations in
// the order of their vertex's first side; the hole corners of boundary sides follow the sides'
// corners, and the hole loops, labelled, the polygons' faces, in close_boundaries()' order.
// This writes those arrays once, in place (RawArrays, like marching cubes), with the report's
// topology figures, and gives up on anything else: the Dlfl is then emptied and the positions
// handed back, for the general path.

#include <algorithm>
#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/polygon_import.h"
#include "prefault.h"
#include "raw_arrays.h"

namespace bisturi::construction {

namespace manifold_detail {

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

}  // namespace manifold_detail

/// `vertex_of(h)`: the (welded) vertex of side h of the kept polygons; `offsets`: CSR over them.
/// On success the Dlfl holds the mesh (it must be empty before), `positions` is moved into it
/// and the topology fields of `report` are set (vertices, isolated_vertices, edges, faces,
/// nonmanifold_*, flipped_faces, seam_edges, duplicate_faces, parts).
template <class CornerVertex>
bool write_manifold(Dlfl& d, const CornerVertex& vertex_of, std::span<const std::uint32_t> offsets,
                    BigVector<Dlfl::Vec3>& positions, ImportReport& report) {
  using namespace manifold_detail;
  const std::size_t nv = positions.size();
  const std::size_t nf = offsets.size() - 1;
  const std::size_t nh = offsets[nf];
  // The tag bits must stay free: part numbers on vertices, twin marks on sides.
  if (nh >= kPartTag / 2 || nv >= kPartTag || nf == 0) return false;

  // Which vertices the polygons use; the others become lone point spheres (k of them). `head`
  // later starts each vertex's list of leaving sides, linked through the corners' prev fields
  // (prev is written last), so the lists cost no memory of their own.
  constexpr std::uint32_t kUnused = 0xffffffffu;
  constexpr std::uint32_t kEndOfList = 0xfffffffeu;
  ScratchVector<std::uint32_t> head;
  reserve_mapped(head, nv);
  head.assign(nv, kUnused);
  for (std::uint32_t h = 0; h < nh; ++h)
    head[vertex_of(h)] = kEndOfList;
  const auto k = static_cast<std::uint32_t>(std::count(head.begin(), head.end(), kUnused));

  // Edges and faces are sized once their numbers are known (boundaries add both).
  RawArrays::View w = RawArrays::size_empty(d, std::move(positions), nh + k, 0, 0, 0);
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
      w.rotations[s].corner = CornerId(s);
      w.vertices[v].first = RotationId(s);
      ++s;
    }
  }

  // Corners; a vertex's rotation is numbered (and anchored) at its first side.
  Dlfl::CornerRecord* corners = w.corners + k;  // indexed by side
  std::uint32_t rotation = k;
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t e = offsets[f + 1];
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

  // Twins: side h (a -> b) pairs with the one side b -> a; the edge fields hold the twin (tagged)
  // until the edges are numbered. Several, or one already paired (an edge in three or more
  // faces, or run twice one way), leaves the fast path. None makes h a boundary side, if it is
  // the only side a -> b and the only boundary side leaving a and entering b (else a flip, a
  // fin or a bow-tie). Parts are joined across every edge on the way (vertex union-find).
  constexpr std::uint32_t kTwinTag = kPartTag;
  constexpr std::uint32_t kNoTwin = kTwinTag | 0x7ffffffeu;
  ScratchVector<std::uint32_t> parent;
  reserve_mapped(parent, nv);
  parent.resize(nv);
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
  ScratchVector<std::uint32_t> boundary_out, boundary_in;  // per vertex; for open input only
  std::uint32_t nb = 0;
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
    if (matches == 1) {
      if (corners[twin].edge.valid()) return give_up();
      corners[h].edge = EdgeId(kTwinTag | twin);
      corners[twin].edge = EdgeId(kTwinTag | h);
    } else {
      if (matches != 0) return give_up();
      std::uint32_t same = 0;
      for (std::uint32_t x = head[a]; x != kEndOfList; x = corners[x].prev.idx)
        same += head_vertex(x) == b ? 1 : 0;
      if (same != 1) return give_up();
      if (boundary_out.empty()) {
        reserve_mapped(boundary_out, nv);
        reserve_mapped(boundary_in, nv);
        boundary_out.assign(nv, kUnused);
        boundary_in.assign(nv, kUnused);
      }
      if (boundary_out[a] != kUnused || boundary_in[b] != kUnused) return give_up();
      boundary_out[a] = h;
      boundary_in[b] = h;
      corners[h].edge = EdgeId(kNoTwin);
      ++nb;
    }
    const std::uint32_t ra = root(a);
    const std::uint32_t rb = root(b);
    if (ra != rb) parent[std::max(ra, rb)] = std::min(ra, rb);
  }
  // A hole corner for every boundary side, after the polygons' corners.
  const auto first_hole = static_cast<std::uint32_t>(k + nh);
  w = RawArrays::grow(d, std::size_t{first_hole} + nb, (nh + nb) / 2);
  corners = w.corners + k;
  // Edges in the order of their first side.
  {
    std::uint32_t edge_count = 0;
    for (std::uint32_t h = 0; h < nh; ++h) {
      const std::uint32_t t = corners[h].edge.idx;
      if ((t & kTwinTag) == 0) continue;  // numbered at its twin
      const EdgeId edge(edge_count++);
      corners[h].edge = edge;
      if (t == kNoTwin) {
        w.edges[edge.idx].a = CornerId(k + h);  // b: the hole corner, numbered below
        continue;
      }
      w.edges[edge.idx] = {CornerId(k + h), CornerId(k + (t & ~kTwinTag))};
      corners[t & ~kTwinTag].edge = edge;
    }
  }
  // The lists are done with: prev takes its meaning.
  for (std::uint32_t f = 0; f < nf; ++f) {
    const std::uint32_t b = offsets[f];
    const std::uint32_t e = offsets[f + 1];
    corners[b].prev = CornerId(k + e - 1);
    for (std::uint32_t h = b + 1; h < e; ++h)
      corners[h].prev = CornerId(k + h - 1);
  }

  // Holes, numbered as close_boundaries() makes them: vertex by vertex in rotation order, the
  // hole of the boundary side entering the vertex, then that of the one leaving it. The hole of
  // side a -> b runs b -> a; the next hole leaves a. Hole loops become labelled faces.
  std::size_t loops = 0;
  if (nb > 0) {
    std::uint32_t holes = 0;
    auto make_hole = [&](std::uint32_t side) {
      CornerPair& pair = w.edges[corners[side].edge.idx];
      if (pair.b.valid()) return;
      const std::uint32_t c = first_hole + holes++;
      pair.b = CornerId(c);
      w.corners[c].vertex = VertexId(head_vertex(side));
      w.corners[c].edge = corners[side].edge;
    };
    for (std::uint32_t r = k; r < rotation; ++r) {
      const std::uint32_t v = w.corners[w.rotations[r].corner.idx].vertex.idx;
      const bool leaves = boundary_out[v] != kUnused;
      if (leaves != (boundary_in[v] != kUnused)) return give_up();
      if (!leaves) continue;
      make_hole(boundary_in[v]);
      make_hole(boundary_out[v]);
    }
    for (std::uint32_t c = first_hole; c < first_hole + nb; ++c) {
      const std::uint32_t enters = corners[w.edges[w.corners[c].edge.idx].a.idx - k].vertex.idx;
      const CornerId next = w.edges[corners[boundary_in[enters]].edge.idx].b;
      w.corners[c].next = next;
      w.corners[next.idx].prev = CornerId(c);
    }
    // Hole loops, numbered in the order of their first corner.
    for (std::uint32_t c = first_hole; c < first_hole + nb; ++c) {
      if (w.corners[c].face.valid()) continue;
      const FaceId face(static_cast<std::uint32_t>(k + nf + loops++));
      std::uint32_t x = c;
      do {
        w.corners[x].face = face;
        x = w.corners[x].next.idx;
      } while (x != c);
    }
  }
  // Faces: point spheres, polygons, labelled hole loops.
  w = RawArrays::grow_faces(d, k + nf + loops);
  corners = w.corners + k;
  for (std::uint32_t s = 0; s < k; ++s)
    w.faces[s].first = CornerId(s);
  for (std::uint32_t f = 0; f < nf; ++f)
    w.faces[k + f].first = CornerId(k + offsets[f]);
  for (std::uint32_t c = first_hole; c < first_hole + nb; ++c) {
    const FaceId face = w.corners[c].face;
    if (w.bounding[face.idx] != 0) continue;
    w.faces[face.idx].first = CornerId(c);
    w.bounding[face.idx] = 1;
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
    } while (x != first && covered <= std::size_t{nh} + nb);
  }
  if (covered != std::size_t{nh} + nb) return give_up();

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
  // A boundary side is an edge of its own (one side where others have two), a hole face a loop.
  for (std::uint32_t c = first_hole; c < first_hole + nb; ++c) {
    ImportPart& part = parts[part_of(w.corners[c].vertex.idx) & ~kPartTag];
    ++part.edges;
    if (w.faces[w.corners[c].face.idx].first.idx == c) ++part.boundary_loops;
  }
  for (ImportPart& part : parts) {
    part.edges /= 2;
    part.closed = part.boundary_loops == 0;
    part.orientable = true;
    part.euler = static_cast<std::int64_t>(part.vertices) - static_cast<std::int64_t>(part.edges) +
                 static_cast<std::int64_t>(part.faces);
    part.genus = (2 - part.euler - static_cast<std::int64_t>(part.boundary_loops)) / 2;
  }

  RawArrays::finish(d, std::size_t{k} + 1);  // create_vertex per sphere, then the bulk write
  report.vertices = nv - k;
  report.isolated_vertices = k;
  report.edges = (nh + nb) / 2;
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
