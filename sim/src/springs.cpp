#include "bisturi/sim/springs.h"

#include <algorithm>
#include <cmath>
#include <tuple>

#include <glm/geometric.hpp>

namespace bisturi::sim {
namespace {

struct Key {
  std::uint32_t a, b;
  SpringKind kind;
  auto operator<=>(const Key&) const = default;
};

void add_pair(std::vector<Key>& keys, std::uint32_t a, std::uint32_t b, SpringKind kind) {
  if (a == b) return;
  keys.push_back({std::min(a, b), std::max(a, b), kind});
}

bool real_face(const Dlfl& mesh, FaceId f) {
  return !mesh.is_bounding(f) && !mesh.is_point_sphere(mesh.first_corner(f));
}

}  // namespace

std::vector<Spring> build_springs(const Dlfl& mesh, const std::vector<glm::dvec3>& rest,
                                  const Material& material) {
  std::vector<Key> keys;
  keys.reserve(mesh.num_edges() * 3);
  std::vector<std::uint32_t> ring;
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh.alive(f) || !real_face(mesh, f)) continue;
    ring.clear();
    const CornerId first = mesh.first_corner(f);
    CornerId c = first;
    do {
      ring.push_back(mesh.vertex(c).idx);
      c = mesh.next(c);
    } while (c != first);
    const std::size_t n = ring.size();
    for (std::size_t i = 0; i < n; ++i) {
      // Structural: every side (the edge's other face adds it again; duplicates go below).
      add_pair(keys, ring[i], ring[(i + 1) % n], SpringKind::Structural);
      // Shear: diagonals of faces with more than three corners.
      for (std::size_t j = i + 2; j < n; ++j) {
        if (i == 0 && j == n - 1) continue;
        add_pair(keys, ring[i], ring[j], SpringKind::Shear);
      }
    }
  }
  // Structural springs on edges with no real face (wires) and bending springs across edges.
  for (std::uint32_t ei = 0; ei < mesh.edge_capacity(); ++ei) {
    const EdgeId e(ei);
    if (!mesh.alive(e)) continue;
    const CornerPair p = mesh.primary_pair(e);
    add_pair(keys, mesh.vertex(p.a).idx, mesh.vertex(p.b).idx, SpringKind::Structural);
    if (!real_face(mesh, mesh.face(p.a)) || !real_face(mesh, mesh.face(p.b))) continue;
    // The vertex after the edge's far end in each face: the opposite vertex of a triangle.
    const VertexId u = mesh.vertex(mesh.next(mesh.next(p.a)));
    const VertexId w = mesh.vertex(mesh.next(mesh.next(p.b)));
    add_pair(keys, u.idx, w.idx, SpringKind::Bending);
  }
  std::sort(keys.begin(), keys.end());
  // One spring per vertex pair: a structural spring wins over shear and bending on the same pair.
  std::vector<Spring> springs;
  springs.reserve(keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (i > 0 && keys[i].a == keys[i - 1].a && keys[i].b == keys[i - 1].b) continue;
    Spring s;
    s.a = keys[i].a;
    s.b = keys[i].b;
    s.kind = keys[i].kind;
    s.rest_m = glm::length(rest[s.b] - rest[s.a]);
    switch (s.kind) {
      case SpringKind::Structural:
        s.k_N_per_m = material.structural_N_per_m;
        break;
      case SpringKind::Shear:
        s.k_N_per_m = material.shear_N_per_m;
        break;
      case SpringKind::Bending:
        s.k_N_per_m = material.bending_N_per_m;
        break;
    }
    if (s.k_N_per_m > 0.0) springs.push_back(s);
  }
  return springs;
}

SurfaceTriangles triangulate_surface(const Dlfl& mesh) {
  SurfaceTriangles t;
  t.indices.reserve(mesh.num_corners() * 3);
  t.face_of.reserve(mesh.num_corners());
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh.alive(f) || !real_face(mesh, f)) continue;
    const CornerId first = mesh.first_corner(f);
    const std::uint32_t v0 = mesh.vertex(first).idx;
    CornerId c = mesh.next(first);
    while (mesh.next(c) != first) {
      const std::uint32_t v1 = mesh.vertex(c).idx;
      const std::uint32_t v2 = mesh.vertex(mesh.next(c)).idx;
      if (v0 != v1 && v1 != v2 && v0 != v2) {
        t.indices.insert(t.indices.end(), {v0, v1, v2});
        t.face_of.push_back(f);
      }
      c = mesh.next(c);
    }
  }
  return t;
}

}  // namespace bisturi::sim
