#include "bisturi/scene/oriented_builder.h"

#include <algorithm>
#include <cmath>
#include <deque>
#include <string>

#include "bisturi/scene/errors.h"

namespace bisturi {

void PolygonMesh::add_face(std::initializer_list<std::uint32_t> face) {
  add_face(std::span<const std::uint32_t>(face.begin(), face.size()));
}

void PolygonMesh::add_face(std::span<const std::uint32_t> face) {
  indices.insert(indices.end(), face.begin(), face.end());
  offsets.push_back(static_cast<std::uint32_t>(indices.size()));
}

namespace {

constexpr std::uint32_t kNone = kInvalidIndex;

/// The target rotation system: polygon half-edges first, then one hole half-edge per boundary
/// half-edge, so that every half-edge has a twin.
struct TargetHalfEdges {
  std::vector<std::uint32_t> from, to, next, twin, face;
  std::vector<std::uint32_t> hole_loops;             // one hole half-edge per boundary loop
  std::vector<std::uint32_t> out_offsets, out_list;  // outgoing half-edges per vertex (CSR)
};

void check_input(const PolygonMesh& mesh) {
  const std::size_t nv = mesh.positions.size();
  for (std::size_t v = 0; v < nv; ++v) {
    const auto& p = mesh.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      throw InputError("vertex " + std::to_string(v) + " has a non-finite coordinate");
    }
  }
  if (mesh.offsets.empty() || mesh.offsets.back() != mesh.indices.size()) {
    throw InputError("polygon offsets do not cover the index array");
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    if (face.size() < 3) {
      throw InputError("face " + std::to_string(f) + " has " + std::to_string(face.size()) +
                       " vertices (at least 3 needed)");
    }
    for (std::size_t k = 0; k < face.size(); ++k) {
      if (face[k] >= nv) {
        throw InputError("face " + std::to_string(f) + ": vertex index " + std::to_string(face[k]) +
                         " is out of range (" + std::to_string(nv) + " vertices)");
      }
      if (face[k] == face[(k + 1) % face.size()]) {
        throw InputError("face " + std::to_string(f) + " repeats vertex " +
                         std::to_string(face[k]) + " on consecutive corners");
      }
    }
  }
}

void build_out_lists(TargetHalfEdges& t, std::size_t nv) {
  t.out_offsets.assign(nv + 1, 0);
  for (std::uint32_t u : t.from)
    ++t.out_offsets[u + 1];
  for (std::size_t v = 0; v < nv; ++v)
    t.out_offsets[v + 1] += t.out_offsets[v];
  t.out_list.assign(t.from.size(), 0);
  std::vector<std::uint32_t> fill(t.out_offsets.begin(), t.out_offsets.end() - 1);
  for (std::uint32_t h = 0; h < t.from.size(); ++h)
    t.out_list[fill[t.from[h]]++] = h;
}

TargetHalfEdges read_target(const PolygonMesh& mesh) {
  const std::size_t nv = mesh.positions.size();
  TargetHalfEdges t;
  const std::size_t nh = mesh.indices.size();
  t.from.resize(nh);
  t.to.resize(nh);
  t.next.resize(nh);
  t.face.resize(nh);
  for (std::uint32_t f = 0; f < mesh.face_count(); ++f) {
    const std::uint32_t begin = mesh.offsets[f];
    const std::uint32_t end = mesh.offsets[f + 1];
    for (std::uint32_t h = begin; h < end; ++h) {
      const std::uint32_t n = h + 1 == end ? begin : h + 1;
      t.from[h] = mesh.indices[h];
      t.to[h] = mesh.indices[n];
      t.next[h] = n;
      t.face[h] = f;
    }
  }
  build_out_lists(t, nv);

  // Twins, and the same directed edge twice (inconsistent orientation or an edge in 3+ faces).
  t.twin.assign(nh, kNone);
  for (std::uint32_t u = 0; u < nv; ++u) {
    auto first = t.out_list.begin() + t.out_offsets[u];
    auto last = t.out_list.begin() + t.out_offsets[u + 1];
    std::sort(first, last, [&](std::uint32_t a, std::uint32_t b) { return t.to[a] < t.to[b]; });
    for (auto it = first; it != last; ++it) {
      if (it + 1 != last && t.to[*it] == t.to[*(it + 1)]) {
        throw InputError("edge " + std::to_string(u) + "-" + std::to_string(t.to[*it]) +
                         " runs the same way in faces " + std::to_string(t.face[*it]) + " and " +
                         std::to_string(t.face[*(it + 1)]) +
                         ": the faces are inconsistently oriented or the edge is non-manifold");
      }
    }
  }
  for (std::uint32_t h = 0; h < nh; ++h) {
    const std::uint32_t w = t.to[h];
    for (std::uint32_t k = t.out_offsets[w]; k < t.out_offsets[w + 1]; ++k) {
      if (t.to[t.out_list[k]] == t.from[h]) {
        t.twin[h] = t.out_list[k];
        break;
      }
    }
  }

  // Close every boundary loop with a hole face (the future labelled face).
  std::vector<std::uint32_t> boundary_into(nv, kNone);
  std::vector<std::uint32_t> hole_of(nh, kNone);
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (t.twin[h] != kNone) continue;
    if (boundary_into[t.to[h]] != kNone) {
      throw InputError("vertex " + std::to_string(t.to[h]) +
                       " joins two boundary fans (a bow-tie vertex): not a manifold vertex");
    }
    boundary_into[t.to[h]] = h;
    hole_of[h] = static_cast<std::uint32_t>(t.from.size());
    t.from.push_back(t.to[h]);
    t.to.push_back(t.from[h]);
    t.twin.push_back(h);
    t.face.push_back(kNone);
    t.next.push_back(kNone);
  }
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (hole_of[h] == kNone) continue;
    t.twin[h] = hole_of[h];
    // The hole half-edge (w->u) continues along the boundary half-edge that enters u.
    t.next[hole_of[h]] = hole_of[boundary_into[t.from[h]]];
  }
  std::vector<char> traced(t.from.size(), 0);
  for (std::uint32_t k = static_cast<std::uint32_t>(nh); k < t.from.size(); ++k) {
    if (traced[k]) continue;
    t.hole_loops.push_back(k);
    for (std::uint32_t x = k; !traced[x]; x = t.next[x])
      traced[x] = 1;
  }
  build_out_lists(t, nv);

  // Each vertex must have one fan: its outgoing half-edges form one rotation cycle.
  std::vector<std::uint32_t> prev(t.from.size());
  for (std::uint32_t h = 0; h < t.from.size(); ++h)
    prev[t.next[h]] = h;
  for (std::uint32_t u = 0; u < nv; ++u) {
    const std::uint32_t count = t.out_offsets[u + 1] - t.out_offsets[u];
    if (count == 0) continue;
    const std::uint32_t start = t.out_list[t.out_offsets[u]];
    std::uint32_t steps = 0;
    std::uint32_t h = start;
    do {
      ++steps;
      h = t.twin[prev[h]];
    } while (h != start && steps <= count);
    if (steps != count) {
      throw InputError("vertex " + std::to_string(u) +
                       " is non-manifold: its faces form more than one fan");
    }
  }
  return t;
}

}  // namespace

std::vector<VertexId> append_oriented_manifold(Dlfl& dlfl, const PolygonMesh& mesh,
                                               const BuildOptions& options) {
  check_input(mesh);
  const std::size_t nv = mesh.positions.size();
  if (!options.join_vertices.empty()) {
    if (options.join_vertices.size() != nv) {
      throw InputError("join_vertices has " + std::to_string(options.join_vertices.size()) +
                       " entries for " + std::to_string(nv) + " vertices");
    }
    for (std::size_t i = 0; i < nv; ++i) {
      const VertexId v = options.join_vertices[i];
      if (v.valid() && !dlfl.alive(v)) {
        throw InputError("join_vertices[" + std::to_string(i) + "] names " + to_string(v) +
                         ", which is not a live vertex of the mesh");
      }
    }
  }
  const TargetHalfEdges t = read_target(mesh);

  // ---- input accepted: build ----
  // Final sizes are known: one corner per half-edge, one edge per twin pair, one face per
  // polygon and per hole. Reserving avoids growth slack in the arrays that stay.
  dlfl.reserve(dlfl.vertex_capacity() + nv, dlfl.corner_capacity() + t.from.size(),
               dlfl.face_capacity() + mesh.face_count() + t.hole_loops.size(),
               dlfl.edge_capacity() + t.from.size() / 2);
  std::vector<VertexId> vertices(nv);
  std::vector<CornerId> sphere(nv);
  for (std::size_t i = 0; i < nv; ++i) {
    const VertexId join = options.join_vertices.empty() ? VertexId{} : options.join_vertices[i];
    if (join.valid()) {
      vertices[i] = join;
      sphere[i] = dlfl.add_rotation(join).corner;
    } else {
      vertices[i] = dlfl.create_vertex(mesh.positions[i]);
      sphere[i] = dlfl.rotation_corner(dlfl.first_rotation(vertices[i]));
    }
  }

  const std::size_t nh = t.from.size();
  std::vector<CornerId> corner_of(nh);
  // The corner after which half-edge h belongs in the rotation of its tail: the nearest
  // already-inserted predecessor in the target rotation, or the point sphere if none.
  auto corner_for = [&](std::uint32_t h) {
    for (std::uint32_t g = t.next[t.twin[h]]; g != h; g = t.next[t.twin[g]]) {
      if (corner_of[g].valid()) return corner_of[g];
    }
    return sphere[t.from[h]];
  };
  const std::size_t total = nh / 2;
  std::size_t done = 0;
  const std::size_t report_every = std::max<std::size_t>(1, total / 100);
  InsertEdgeOptions insert_options;
  insert_options.check_label_orientation = false;
  auto insert = [&](std::uint32_t h) {
    const InsertEdgeResult r =
        dlfl.insert_edge(corner_for(h), corner_for(t.twin[h]), insert_options);
    corner_of[h] = r.side12;
    corner_of[t.twin[h]] = r.side21;
    if (options.progress && ++done % report_every == 0) options.progress(done, total);
  };

  // Spanning forest first (every insertion merges a point sphere), then the other edges.
  std::vector<char> reached(nv, 0);
  std::deque<std::uint32_t> queue;
  for (std::uint32_t s = 0; s < nv; ++s) {
    if (reached[s]) continue;
    reached[s] = 1;
    queue.push_back(s);
    while (!queue.empty()) {
      const std::uint32_t u = queue.front();
      queue.pop_front();
      for (std::uint32_t k = t.out_offsets[u]; k < t.out_offsets[u + 1]; ++k) {
        const std::uint32_t h = t.out_list[k];
        if (reached[t.to[h]]) continue;
        reached[t.to[h]] = 1;
        queue.push_back(t.to[h]);
        insert(h);
      }
    }
  }
  for (std::uint32_t h = 0; h < nh; ++h) {
    if (!corner_of[h].valid()) insert(h);
  }
  for (std::uint32_t k : t.hole_loops)
    dlfl.set_bounding(dlfl.face(corner_of[k]), true);
  if (options.progress) options.progress(total, total);
  return vertices;
}

Dlfl build_oriented_manifold(const PolygonMesh& mesh, const BuildOptions& options) {
  Dlfl dlfl;
  append_oriented_manifold(dlfl, mesh, options);
  return dlfl;
}

}  // namespace bisturi
