#include "bisturi/sim/springs.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include "bisturi/sim/errors.h"
#include "vertex_corners.h"

namespace bisturi::sim {
namespace {

/// A spring candidate packed into one integer whose order is (a, b, kind): a in the top 30
/// bits, b in the next 32, the kind in the low 2. Sorting integers is several times faster than
/// sorting a struct with a three-way comparison (the sort dominated building a body's springs).
using Key = std::uint64_t;
constexpr std::uint32_t kMaxVertexIndex = (1u << 30) - 1u;

Key make_key(std::uint32_t a, std::uint32_t b, SpringKind kind) {
  return (Key{a} << 34) | (Key{b} << 2) | Key{static_cast<std::uint8_t>(kind)};
}
std::uint32_t key_a(Key k) {
  return static_cast<std::uint32_t>(k >> 34);
}
std::uint32_t key_b(Key k) {
  return static_cast<std::uint32_t>(k >> 2);
}
SpringKind key_kind(Key k) {
  return static_cast<SpringKind>(k & 3u);
}

void add_pair(std::vector<Key>& keys, std::uint32_t a, std::uint32_t b, SpringKind kind) {
  if (a == b) return;
  if (std::max(a, b) > kMaxVertexIndex) throw SimInputError("springs: more than 2^30 vertex slots");
  keys.push_back(make_key(std::min(a, b), std::max(a, b), kind));
}

bool real_face(const Dlfl& mesh, FaceId f) {
  return !mesh.is_bounding(f) && !mesh.is_point_sphere(mesh.first_corner(f));
}

/// Structural springs on the sides of a real face and shear springs across its diagonals.
void add_face_keys(const Dlfl& mesh, FaceId f, std::vector<std::uint32_t>& ring,
                   std::vector<Key>& keys) {
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

/// A structural spring on the edge (for wires with no real face) and the bending spring across
/// it.
void add_edge_keys(const Dlfl& mesh, EdgeId e, std::vector<Key>& keys) {
  const CornerPair p = mesh.primary_pair(e);
  add_pair(keys, mesh.vertex(p.a).idx, mesh.vertex(p.b).idx, SpringKind::Structural);
  if (!real_face(mesh, mesh.face(p.a)) || !real_face(mesh, mesh.face(p.b))) return;
  // The vertex after the edge's far end in each face: the opposite vertex of a triangle.
  const VertexId u = mesh.vertex(mesh.next(mesh.next(p.a)));
  const VertexId w = mesh.vertex(mesh.next(mesh.next(p.b)));
  add_pair(keys, u.idx, w.idx, SpringKind::Bending);
}

/// Sorts the keys: a counting sort by the first end, then each vertex's few keys by std::sort
/// (a comparison sort of the whole list was most of the time of making a body).
void sort_keys(std::vector<Key>& keys) {
  if (keys.size() < 4096) {
    std::sort(keys.begin(), keys.end());
    return;
  }
  std::uint32_t n = 0;
  for (const Key k : keys)
    n = std::max(n, key_a(k) + 1);
  std::vector<std::uint32_t> start(std::size_t{n} + 1, 0);
  for (const Key k : keys)
    ++start[key_a(k) + 1];
  for (std::size_t a = 0; a < n; ++a)
    start[a + 1] += start[a];
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  std::vector<Key> sorted(keys.size());
  for (const Key k : keys)
    sorted[fill[key_a(k)]++] = k;
  for (std::size_t a = 0; a < n; ++a)
    std::sort(sorted.begin() + start[a], sorted.begin() + start[a + 1]);
  keys.swap(sorted);
}

/// Sorted keys to springs: one per vertex pair, a structural spring winning over shear and
/// bending on the same pair.
std::vector<Spring> springs_from_keys(std::vector<Key>& keys, const std::vector<glm::dvec3>& rest,
                                      const Material& material) {
  sort_keys(keys);
  std::vector<Spring> springs;
  springs.reserve(keys.size());
  for (std::size_t i = 0; i < keys.size(); ++i) {
    if (i > 0 && (keys[i] >> 2) == (keys[i - 1] >> 2)) continue;  // the same pair
    Spring s;
    s.a = key_a(keys[i]);
    s.b = key_b(keys[i]);
    s.kind = key_kind(keys[i]);
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

}  // namespace

std::vector<Spring> build_springs(const Dlfl& mesh, const std::vector<glm::dvec3>& rest,
                                  const Material& material) {
  std::vector<Key> keys;
  keys.reserve(mesh.num_edges() * 3);
  std::vector<std::uint32_t> ring;
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (mesh.alive(f) && real_face(mesh, f)) add_face_keys(mesh, f, ring, keys);
  }
  // Structural springs on edges with no real face (wires) and bending springs across edges.
  for (std::uint32_t ei = 0; ei < mesh.edge_capacity(); ++ei) {
    if (mesh.alive(EdgeId(ei))) add_edge_keys(mesh, EdgeId(ei), keys);
  }
  return springs_from_keys(keys, rest, material);
}

std::vector<FaceId> faces_around(const Dlfl& mesh, std::span<const std::uint32_t> vertices) {
  std::vector<FaceId> faces;
  for (std::uint32_t v : vertices)
    for_each_corner(mesh, VertexId(v), [&](CornerId c) { faces.push_back(mesh.face(c)); });
  std::sort(faces.begin(), faces.end());
  faces.erase(std::unique(faces.begin(), faces.end()), faces.end());
  return faces;
}

std::vector<Spring> build_springs_near(const Dlfl& mesh, const std::vector<glm::dvec3>& rest,
                                       const Material& material,
                                       const std::vector<std::uint8_t>& region,
                                       std::span<const FaceId> faces) {
  // A spring with an end v in the region comes from a face around v (structural, shear), or
  // from an edge of such a face (a bending spring's ends are corners of the edge's two faces).
  std::vector<Key> keys;
  std::vector<EdgeId> edges;
  std::vector<std::uint32_t> ring;
  for (FaceId f : faces) {
    if (!mesh.alive(f)) continue;
    if (real_face(mesh, f)) add_face_keys(mesh, f, ring, keys);
    const CornerId first = mesh.first_corner(f);
    CornerId c = first;
    do {
      const EdgeId e = mesh.edge(c);
      if (e.valid() && mesh.alive(e)) edges.push_back(e);
      c = mesh.next(c);
    } while (c != first);
  }
  std::sort(edges.begin(), edges.end());
  edges.erase(std::unique(edges.begin(), edges.end()), edges.end());
  for (EdgeId e : edges)
    add_edge_keys(mesh, e, keys);
  std::erase_if(keys, [&](Key k) { return !region[key_a(k)] && !region[key_b(k)]; });
  return springs_from_keys(keys, rest, material);
}

namespace {

/// Appends the fan of face f (alive and real) to t: corner 0 with each later side, skipping
/// degenerate triangles.
void add_face_triangles(const Dlfl& mesh, FaceId f, SurfaceTriangles& t) {
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

}  // namespace

SurfaceTriangles triangulate_surface(const Dlfl& mesh) {
  SurfaceTriangles t;
  t.indices.reserve(mesh.num_corners() * 3);
  t.face_of.reserve(mesh.num_corners());
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (mesh.alive(f) && real_face(mesh, f)) add_face_triangles(mesh, f, t);
  }
  return t;
}

void triangulate_changed_faces(const Dlfl& mesh, const SurfaceTriangles& before,
                               std::span<const FaceId> changed, SurfaceTriangles& out) {
  // The changed faces are triangulated again first; then a merge in face order of their
  // triangles and the unchanged faces' runs of old triangles (copied while the face is alive).
  SurfaceTriangles fresh;
  for (const FaceId f : changed)
    if (mesh.alive(f) && real_face(mesh, f)) add_face_triangles(mesh, f, fresh);
  const std::size_t nb = before.size(), nf = fresh.size();
  out.indices.resize(3 * (nb + nf));
  out.face_of.resize(nb + nf);
  std::uint32_t* oi = out.indices.data();
  FaceId* of = out.face_of.data();
  const std::uint32_t* bi = before.indices.data();
  const FaceId* bf = before.face_of.data();
  std::size_t n = 0, i = 0, j = 0, c = 0;
  auto put = [&](const std::uint32_t* idx, FaceId f) {
    oi[3 * n] = idx[0];
    oi[3 * n + 1] = idx[1];
    oi[3 * n + 2] = idx[2];
    of[n++] = f;
  };
  constexpr std::uint32_t kEnd = std::numeric_limits<std::uint32_t>::max();
  while (i < nb || j < nf) {
    const std::uint32_t fb = i < nb ? bf[i].idx : kEnd;
    // The next changed face at or after fb: its old triangles are dropped, its new ones go in
    // before any later face's.
    while (c < changed.size() && changed[c].idx < fb)
      ++c;
    const bool replaced = c < changed.size() && changed[c].idx == fb;
    const std::uint32_t fj = j < nf ? fresh.face_of[j].idx : kEnd;
    if (fj <= fb) {
      put(fresh.indices.data() + 3 * j, fresh.face_of[j]);
      ++j;
      continue;
    }
    std::size_t run = i + 1;
    while (run < nb && bf[run].idx == fb)
      ++run;
    if (!replaced && mesh.alive(FaceId(fb))) {
      for (std::size_t t = i; t < run; ++t)
        put(bi + 3 * t, bf[t]);
    }
    i = run;
  }
  out.indices.resize(3 * n);
  out.face_of.resize(n);
}

}  // namespace bisturi::sim
