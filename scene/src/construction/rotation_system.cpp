#include "rotation_system.h"

#include <algorithm>
#include <deque>

namespace bisturi::construction {

void read_polygon_half_edges(std::span<const std::uint32_t> indices,
                             std::span<const std::uint32_t> offsets, RotationSystem& rs) {
  const std::size_t nh = indices.size();
  rs.from.resize(nh);
  rs.to.resize(nh);
  rs.next.resize(nh);
  rs.twin.assign(nh, kNone);
  for (std::size_t f = 0; f + 1 < offsets.size(); ++f) {
    const std::uint32_t begin = offsets[f];
    const std::uint32_t end = offsets[f + 1];
    for (std::uint32_t h = begin; h < end; ++h) {
      const std::uint32_t n = h + 1 == end ? begin : h + 1;
      rs.from[h] = indices[h];
      rs.to[h] = indices[n];
      rs.next[h] = n;
    }
  }
  rs.face_half_edges = static_cast<std::uint32_t>(nh);
}

void close_boundaries(RotationSystem& rs) {
  const std::uint32_t nh = rs.face_half_edges;
  ScratchVector<std::uint32_t> prev(nh);
  for (std::uint32_t h = 0; h < nh; ++h)
    prev[rs.next[h]] = h;
  ScratchVector<char> boundary(nh);
  std::size_t holes = 0;
  for (std::uint32_t h = 0; h < nh; ++h) {
    boundary[h] = rs.twin[h] == kNone ? 1 : 0;
    holes += boundary[h];
  }
  // One hole half-edge per boundary side: exact room, so appending them never regrows.
  for (auto* array : {&rs.from, &rs.to, &rs.next, &rs.twin})
    array->reserve(nh + holes);
  rs.fan.reserve(nh + holes);

  ScratchVector<std::uint32_t> hole_of(nh, kNone);
  auto hole = [&](std::uint32_t b) {
    if (hole_of[b] == kNone) {
      hole_of[b] = static_cast<std::uint32_t>(rs.from.size());
      rs.from.push_back(rs.to[b]);
      rs.to.push_back(rs.from[b]);
      rs.next.push_back(kNone);
      rs.twin.push_back(b);
      rs.fan.push_back(kNone);
      rs.twin[b] = hole_of[b];
    }
    return hole_of[b];
  };

  rs.fan.assign(nh, kNone);
  rs.fan_vertex.clear();
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (rs.fan[h] != kNone) continue;
    // Back to the first half-edge of the fan (rot_prev(x) = next(twin(x))), or around it.
    std::uint32_t start = h;
    for (std::uint32_t steps = 0; steps <= nh && !boundary[start]; ++steps) {
      const std::uint32_t back = rs.next[rs.twin[start]];
      if (back == h) break;
      start = back;
    }
    const auto id = static_cast<std::uint32_t>(rs.fan_vertex.size());
    rs.fan_vertex.push_back(rs.from[h]);
    // Forward (rot_next(x) = twin(prev(x))) until the fan closes or its last face ends on a
    // boundary half-edge entering the vertex; the hole then runs from start's hole to it.
    std::uint32_t x = start;
    for (std::uint32_t steps = 0; steps <= nh; ++steps) {
      rs.fan[x] = id;
      const std::uint32_t entering = prev[x];
      if (boundary[entering]) {
        const std::uint32_t leaving_hole = hole(entering);
        rs.next[hole(start)] = leaving_hole;
        rs.fan[leaving_hole] = id;
        break;
      }
      x = rs.twin[entering];
      if (x == start) break;
    }
  }

  rs.hole_loops.clear();
  ScratchVector<char> traced(rs.from.size(), 0);
  for (auto k = static_cast<std::uint32_t>(nh); k < rs.from.size(); ++k) {
    if (traced[k]) continue;
    rs.hole_loops.push_back(k);
    for (std::uint32_t x = k; x != kNone && !traced[x]; x = rs.next[x])
      traced[x] = 1;
  }
}

std::vector<VertexId> insert_rotation_system(Dlfl& dlfl, const RotationSystem& rs,
                                             std::span<const Dlfl::Vec3> positions,
                                             const InsertOptions& options,
                                             ScratchVector<CornerId>* corner_of_half_edge) {
  const std::size_t nv = positions.size();
  const std::size_t nh = rs.from.size();
  const std::size_t nfans = rs.fan_vertex.size();

  // Final sizes are known: one corner per half-edge, one edge per twin pair, one face per
  // polygon and hole, one rotation per fan. Reserving avoids growth slack in arrays that stay.
  std::size_t polygon_faces = 0;
  for (std::uint32_t h = 0; h < rs.face_half_edges; ++h)
    polygon_faces += rs.next[h] < h ? 1 : 0;
  dlfl.reserve(dlfl.vertex_capacity() + nv, dlfl.corner_capacity() + nh,
               dlfl.face_capacity() + polygon_faces + rs.hole_loops.size(),
               dlfl.edge_capacity() + nh / 2);

  // One rotation per fan: the vertex's first fan takes the rotation create_vertex makes.
  ScratchVector<std::uint32_t> fan_offsets(nv + 1, 0);  // fans of each vertex (CSR), in fan order
  for (std::uint32_t f = 0; f < nfans; ++f)
    ++fan_offsets[rs.fan_vertex[f] + 1];
  for (std::size_t v = 0; v < nv; ++v)
    fan_offsets[v + 1] += fan_offsets[v];
  ScratchVector<std::uint32_t> fans_by_vertex(nfans);
  {
    ScratchVector<std::uint32_t> fill(fan_offsets.begin(), fan_offsets.end() - 1);
    for (std::uint32_t f = 0; f < nfans; ++f)
      fans_by_vertex[fill[rs.fan_vertex[f]]++] = f;
  }
  std::vector<VertexId> vertices(nv);
  ScratchVector<CornerId> sphere(nfans);
  for (std::size_t v = 0; v < nv; ++v) {
    const VertexId join = options.join_vertices.empty() ? VertexId{} : options.join_vertices[v];
    vertices[v] = join.valid() ? join : dlfl.create_vertex(positions[v]);
    for (std::uint32_t i = fan_offsets[v]; i < fan_offsets[v + 1]; ++i) {
      const bool reuse_first = i == fan_offsets[v] && !join.valid();
      sphere[fans_by_vertex[i]] = reuse_first
                                      ? dlfl.rotation_corner(dlfl.first_rotation(vertices[v]))
                                      : dlfl.add_rotation(vertices[v]).corner;
    }
  }

  ScratchVector<CornerId> corner_of(nh);
  // The corner after which half-edge h belongs in its tail's rotation: the nearest inserted
  // predecessor in the target rotation, or the fan's point sphere if none yet.
  auto corner_for = [&](std::uint32_t h) {
    for (std::uint32_t g = rs.next[rs.twin[h]]; g != h; g = rs.next[rs.twin[g]]) {
      if (corner_of[g].valid()) return corner_of[g];
    }
    return sphere[rs.fan[h]];
  };
  const std::size_t total = nh / 2;
  std::size_t done = 0;
  const std::size_t report_every = std::max<std::size_t>(1, total / 100);
  InsertEdgeOptions insert_options;
  insert_options.check_label_orientation = false;
  auto insert = [&](std::uint32_t h) {
    const InsertEdgeResult r =
        dlfl.insert_edge(corner_for(h), corner_for(rs.twin[h]), insert_options);
    corner_of[h] = r.side12;
    corner_of[rs.twin[h]] = r.side21;
    if (options.progress && ++done % report_every == 0) options.progress(done, total);
  };

  // Spanning forest over fans first (every insertion merges a point sphere), then the rest.
  ScratchVector<std::uint32_t> prev(nh);
  for (std::uint32_t h = 0; h < nh; ++h)
    prev[rs.next[h]] = h;
  ScratchVector<std::uint32_t> fan_first(nfans, kNone);
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (fan_first[rs.fan[h]] == kNone) fan_first[rs.fan[h]] = h;
  }
  ScratchVector<char> reached(nfans, 0);
  std::deque<std::uint32_t> queue;
  for (std::uint32_t s = 0; s < nfans; ++s) {
    if (reached[s]) continue;
    reached[s] = 1;
    queue.push_back(s);
    while (!queue.empty()) {
      const std::uint32_t fan = queue.front();
      queue.pop_front();
      const std::uint32_t first = fan_first[fan];
      std::uint32_t x = first;
      do {
        const std::uint32_t other = rs.fan[rs.twin[x]];
        if (!reached[other]) {
          reached[other] = 1;
          queue.push_back(other);
          insert(x);
        }
        x = rs.twin[prev[x]];
      } while (x != first);
    }
  }
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (!corner_of[h].valid()) insert(h);
  }
  for (std::uint32_t k : rs.hole_loops) {
    dlfl.set_bounding(dlfl.face(corner_of[k]), true);
  }
  // Point spheres merged early leave free face slots that later splits reuse: the list ends
  // empty but keeps its peak capacity.
  dlfl.release_empty_free_lists();
  if (options.progress) options.progress(total, total);
  if (corner_of_half_edge != nullptr) *corner_of_half_edge = std::move(corner_of);
  return vertices;
}

}  // namespace bisturi::construction
