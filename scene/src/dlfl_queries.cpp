#include "bisturi/scene/dlfl_queries.h"

#include <algorithm>

namespace bisturi {

std::size_t face_valence(const Dlfl& mesh, FaceId f) {
  std::size_t n = 0;
  const CornerId start = mesh.first_corner(f);
  CornerId c = start;
  do {
    ++n;
    c = mesh.next(c);
  } while (c != start);
  return n;
}

std::size_t vertex_valence(const Dlfl& mesh, VertexId v) {
  std::size_t n = 0;
  for (RotationId r = mesh.first_rotation(v); r.valid(); r = mesh.next_rotation(r)) {
    const CornerId start = mesh.rotation_corner(r);
    if (mesh.is_point_sphere(start)) continue;
    CornerId c = start;
    do {
      ++n;
      c = mesh.rot_next(c);
    } while (c != start);
  }
  return n;
}

std::size_t rotation_count(const Dlfl& mesh, VertexId v) {
  std::size_t n = 0;
  for (RotationId r = mesh.first_rotation(v); r.valid(); r = mesh.next_rotation(r))
    ++n;
  return n;
}

std::vector<CornerId> face_corners(const Dlfl& mesh, FaceId f) {
  std::vector<CornerId> out;
  const CornerId start = mesh.first_corner(f);
  CornerId c = start;
  do {
    out.push_back(c);
    c = mesh.next(c);
  } while (c != start);
  return out;
}

std::vector<VertexId> face_vertices(const Dlfl& mesh, FaceId f) {
  std::vector<VertexId> out;
  for (CornerId c : face_corners(mesh, f))
    out.push_back(mesh.vertex(c));
  return out;
}

std::vector<CornerId> rotation_corners(const Dlfl& mesh, RotationId r) {
  std::vector<CornerId> out;
  const CornerId start = mesh.rotation_corner(r);
  CornerId c = start;
  do {
    out.push_back(c);
    c = mesh.rot_next(c);
  } while (c != start);
  return out;
}

std::vector<std::vector<FaceId>> faces_around_vertex(const Dlfl& mesh, VertexId v) {
  std::vector<std::vector<FaceId>> out;
  for (RotationId r = mesh.first_rotation(v); r.valid(); r = mesh.next_rotation(r)) {
    auto& faces = out.emplace_back();
    for (CornerId c : rotation_corners(mesh, r))
      faces.push_back(mesh.face(c));
  }
  return out;
}

std::vector<FaceId> edge_faces(const Dlfl& mesh, EdgeId e) {
  std::vector<FaceId> out;
  for (const CornerPair& p : mesh.edge_pairs(e)) {
    out.push_back(mesh.face(p.a));
    out.push_back(mesh.face(p.b));
  }
  return out;
}

std::pair<VertexId, VertexId> edge_vertices(const Dlfl& mesh, EdgeId e) {
  const CornerPair p = mesh.primary_pair(e);
  return {mesh.vertex(p.a), mesh.vertex(p.b)};
}

std::vector<FaceId> boundary_loops(const Dlfl& mesh) {
  std::vector<FaceId> out;
  for (std::uint32_t i = 0; i < mesh.face_capacity(); ++i) {
    const FaceId f(i);
    if (mesh.alive(f) && mesh.is_bounding(f) && !mesh.is_point_sphere(mesh.first_corner(f))) {
      out.push_back(f);
    }
  }
  return out;
}

std::vector<EdgeId> non_manifold_edges(const Dlfl& mesh) {
  std::vector<EdgeId> out;
  for (const auto& [edge, pairs] : mesh.extra_pair_lists())
    out.emplace_back(edge);
  return out;
}

std::vector<VertexId> non_manifold_vertices(const Dlfl& mesh) {
  std::vector<VertexId> out;
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (mesh.alive(v) && mesh.next_rotation(mesh.first_rotation(v)).valid()) out.push_back(v);
  }
  return out;
}

std::vector<Part> connected_parts(const Dlfl& mesh) {
  std::vector<Part> parts;
  std::vector<char> seen(mesh.face_capacity(), 0);
  std::vector<FaceId> stack;
  for (std::uint32_t i = 0; i < mesh.face_capacity(); ++i) {
    if (!mesh.alive(FaceId(i)) || seen[i]) continue;
    Part& part = parts.emplace_back();
    seen[i] = 1;
    stack.emplace_back(i);
    while (!stack.empty()) {
      const FaceId f = stack.back();
      stack.pop_back();
      part.faces.push_back(f);
      const CornerId start = mesh.first_corner(f);
      CornerId c = start;
      do {
        const CornerId other = mesh.partner(c);
        if (other.valid()) {
          const FaceId g = mesh.face(other);
          if (!seen[g.idx]) {
            seen[g.idx] = 1;
            stack.push_back(g);
          }
        }
        c = mesh.next(c);
      } while (c != start);
    }
  }
  return parts;
}

PartTopology part_topology(const Dlfl& mesh, const Part& part) {
  PartTopology t;
  std::vector<char> in_rotation(mesh.corner_capacity(), 0);
  std::size_t sides = 0;
  for (FaceId f : part.faces) {
    if (mesh.is_bounding(f)) {
      ++t.rings;
    } else {
      ++t.faces;
    }
    for (CornerId c : face_corners(mesh, f)) {
      if (!mesh.is_point_sphere(c)) ++sides;
      if (in_rotation[c.idx]) continue;
      // A new rotation: mark all its corners (they all lie in this part).
      ++t.vertices;
      CornerId x = c;
      do {
        in_rotation[x.idx] = 1;
        x = mesh.rot_next(x);
      } while (x != c);
    }
  }
  t.edges = sides / 2;
  t.euler_characteristic = static_cast<std::int64_t>(t.vertices) -
                           static_cast<std::int64_t>(t.edges) + static_cast<std::int64_t>(t.faces);
  t.genus = (2 - (t.euler_characteristic + static_cast<std::int64_t>(t.rings))) / 2;
  return t;
}

MeshStatistics mesh_statistics(const Dlfl& mesh) {
  MeshStatistics s;
  s.vertices = mesh.num_vertices();
  s.corners = mesh.num_corners();
  s.faces = mesh.num_faces();
  s.edges = mesh.num_edges();
  s.rotations = mesh.num_rotations();
  for (std::uint32_t i = 0; i < mesh.face_capacity(); ++i) {
    const FaceId f(i);
    if (!mesh.alive(f)) continue;
    if (mesh.is_bounding(f)) ++s.bounding_faces;
    if (mesh.is_point_sphere(mesh.first_corner(f))) ++s.point_spheres;
  }
  s.non_manifold_vertices = non_manifold_vertices(mesh).size();
  s.non_manifold_edges = non_manifold_edges(mesh).size();
  for (const Part& p : connected_parts(mesh))
    s.parts.push_back(part_topology(mesh, p));
  return s;
}

}  // namespace bisturi
