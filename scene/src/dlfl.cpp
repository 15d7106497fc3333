// Element storage, vertex operators, labels and rotations of the DLFL. The edge operators are in
// dlfl_edges.cpp and compact() in dlfl_compact.cpp.

#include "bisturi/scene/dlfl.h"

#include <algorithm>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

template <class Records>
std::uint32_t take_slot(Records& records, std::vector<std::uint32_t>& free_list) {
  if (!free_list.empty()) {
    std::uint32_t i = free_list.back();
    free_list.pop_back();
    return i;
  }
  records.emplace_back();
  return static_cast<std::uint32_t>(records.size() - 1);
}

}  // namespace

// ---------------------------------------------------------------- allocation

VertexId Dlfl::new_vertex() {
  const bool reused = !free_vertices_.empty();
  VertexId v(take_slot(vertices_, free_vertices_));
  if (reused) {
    vertex_props_.reset(v.idx);
    positions_[v.idx] = Vec3(0.0);
  } else {
    positions_.emplace_back(0.0);
    vertex_props_.resize(vertices_.size());
  }
  return v;
}

CornerId Dlfl::new_corner(VertexId v) {
  const bool reused = !free_corners_.empty();
  CornerId c(take_slot(corners_, free_corners_));
  corners_[c.idx] = CornerRecord{v, FaceId{}, c, c, EdgeId{}};
  if (reused) {
    corner_props_.reset(c.idx);
  } else {
    corner_props_.resize(corners_.size());
  }
  return c;
}

FaceId Dlfl::new_face(CornerId first) {
  const bool reused = !free_faces_.empty();
  FaceId f(take_slot(faces_, free_faces_));
  faces_[f.idx].first = first;
  if (reused) {
    bounding_[f.idx] = 0;
    face_props_.reset(f.idx);
  } else {
    bounding_.push_back(0);
    face_props_.resize(faces_.size());
  }
  return f;
}

EdgeId Dlfl::new_edge(CornerPair pair) {
  const bool reused = !free_edges_.empty();
  EdgeId e(take_slot(edges_, free_edges_));
  edges_[e.idx] = pair;
  if (reused) {
    edge_props_.reset(e.idx);
  } else {
    edge_props_.resize(edges_.size());
  }
  return e;
}

RotationId Dlfl::new_rotation(CornerId corner) {
  RotationId r(take_slot(rotations_, free_rotations_));
  rotations_[r.idx] = RotationRecord{corner};
  return r;
}

void Dlfl::free_corner(CornerId c) {
  corners_[c.idx] = CornerRecord{};
  free_corners_.push_back(c.idx);
}

void Dlfl::free_face(FaceId f) {
  faces_[f.idx].first = CornerId{};
  bounding_[f.idx] = 0;
  free_faces_.push_back(f.idx);
}

void Dlfl::free_edge(EdgeId e) {
  edges_[e.idx] = CornerPair{};
  free_edges_.push_back(e.idx);
}

void Dlfl::free_rotation(VertexId v, RotationId r) {
  const RotationId after = next_rotation(r);
  if (vertices_[v.idx].first == r) {
    vertices_[v.idx].first = after;
  } else {
    RotationId before = vertices_[v.idx].first;
    while (next_rotation(before) != r)
      before = next_rotation(before);
    set_next_rotation(before, after);
  }
  set_next_rotation(r, RotationId{});
  rotations_[r.idx] = RotationRecord{};
  free_rotations_.push_back(r.idx);
}

RotationId Dlfl::next_rotation(RotationId r) const {
  if (rotation_links_.empty()) return RotationId{};
  auto it = std::lower_bound(rotation_links_.begin(), rotation_links_.end(), r.idx,
                             [](const auto& link, std::uint32_t key) { return link.first < key; });
  return (it != rotation_links_.end() && it->first == r.idx) ? RotationId(it->second)
                                                             : RotationId{};
}

void Dlfl::set_next_rotation(RotationId r, RotationId next) {
  auto it = std::lower_bound(rotation_links_.begin(), rotation_links_.end(), r.idx,
                             [](const auto& link, std::uint32_t key) { return link.first < key; });
  const bool present = it != rotation_links_.end() && it->first == r.idx;
  if (!next.valid()) {
    if (present) rotation_links_.erase(it);
  } else if (present) {
    it->second = next.idx;
  } else {
    rotation_links_.emplace(it, r.idx, next.idx);
  }
}

RotationId Dlfl::last_rotation(VertexId v) const {
  RotationId r = vertices_[v.idx].first;
  for (RotationId n = next_rotation(r); n.valid(); n = next_rotation(r))
    r = n;
  return r;
}

void Dlfl::reserve(std::size_t n, std::size_t c, std::size_t f, std::size_t e) {
  vertices_.reserve(n);
  positions_.reserve(n);
  rotations_.reserve(n);
  corners_.reserve(c);
  faces_.reserve(f);
  bounding_.reserve(f);
  edges_.reserve(e);
  vertex_props_.reserve(n);
  corner_props_.reserve(c);
  face_props_.reserve(f);
  edge_props_.reserve(e);
}

void Dlfl::release_empty_free_lists() {
  for (auto* list :
       {&free_vertices_, &free_corners_, &free_faces_, &free_edges_, &free_rotations_}) {
    if (list->empty()) list->shrink_to_fit();
  }
}

std::size_t Dlfl::memory_bytes() const {
  std::size_t bytes =
      corners_.capacity() * sizeof(CornerRecord) + faces_.capacity() * sizeof(FaceRecord) +
      edges_.capacity() * sizeof(CornerPair) + vertices_.capacity() * sizeof(VertexRecord) +
      rotations_.capacity() * sizeof(RotationRecord) +
      rotation_links_.capacity() * sizeof(rotation_links_[0]) +
      positions_.capacity() * sizeof(Vec3) + bounding_.capacity();
  for (const auto& [edge, pairs] : extra_pairs_)
    bytes += pairs.capacity() * sizeof(CornerPair);
  bytes += extra_pairs_.capacity() * sizeof(extra_pairs_[0]);
  bytes += (free_vertices_.capacity() + free_corners_.capacity() + free_faces_.capacity() +
            free_edges_.capacity() + free_rotations_.capacity()) *
           sizeof(std::uint32_t);
  return bytes;
}

// ---------------------------------------------------------------- liveness and checks

bool Dlfl::alive(VertexId v) const {
  return v.idx < vertices_.size() && vertices_[v.idx].first.valid();
}
bool Dlfl::alive(CornerId c) const {
  return c.idx < corners_.size() && corners_[c.idx].vertex.valid();
}
bool Dlfl::alive(FaceId f) const {
  return f.idx < faces_.size() && faces_[f.idx].first.valid();
}
bool Dlfl::alive(EdgeId e) const {
  return e.idx < edges_.size() && edges_[e.idx].a.valid();
}
bool Dlfl::alive(RotationId r) const {
  return r.idx < rotations_.size() && rotations_[r.idx].corner.valid();
}

namespace {
template <class Tag>
[[noreturn]] void throw_dead(Handle<Tag> h, const char* op, std::size_t capacity) {
  std::string why = h.idx < capacity ? "was deleted" : "is out of range (foreign or stale handle)";
  if (!h.valid()) why = "is invalid";
  throw TopologyError(std::string(op) + ": " + to_string(h) + " " + why);
}
}  // namespace

void Dlfl::require(VertexId v, const char* op) const {
  if (!alive(v)) throw_dead(v, op, vertices_.size());
}
void Dlfl::require(CornerId c, const char* op) const {
  if (!alive(c)) throw_dead(c, op, corners_.size());
}
void Dlfl::require(FaceId f, const char* op) const {
  if (!alive(f)) throw_dead(f, op, faces_.size());
}
void Dlfl::require(EdgeId e, const char* op) const {
  if (!alive(e)) throw_dead(e, op, edges_.size());
}

// ---------------------------------------------------------------- navigation

std::vector<CornerPair>* Dlfl::extra_pairs_of(EdgeId e) {
  auto it =
      std::lower_bound(extra_pairs_.begin(), extra_pairs_.end(), e.idx,
                       [](const auto& entry, std::uint32_t key) { return entry.first < key; });
  return (it != extra_pairs_.end() && it->first == e.idx) ? &it->second : nullptr;
}

const std::vector<CornerPair>* Dlfl::extra_pairs_of(EdgeId e) const {
  return const_cast<Dlfl*>(this)->extra_pairs_of(e);
}

std::vector<CornerPair> Dlfl::edge_pairs(EdgeId e) const {
  std::vector<CornerPair> pairs{edges_[e.idx]};
  if (const auto* extra = extra_pairs_of(e))
    pairs.insert(pairs.end(), extra->begin(), extra->end());
  return pairs;
}

std::size_t Dlfl::edge_pair_count(EdgeId e) const {
  const auto* extra = extra_pairs_of(e);
  return 1 + (extra != nullptr ? extra->size() : 0);
}

CornerPair Dlfl::pair_of(CornerId c) const {
  const EdgeId e = corners_[c.idx].edge;
  if (!e.valid()) throw TopologyError(to_string(c) + " is a point sphere: it has no edge side");
  const CornerPair& primary = edges_[e.idx];
  if (primary.a == c || primary.b == c) return primary;
  if (const auto* extra = extra_pairs_of(e)) {
    for (const CornerPair& p : *extra) {
      if (p.a == c || p.b == c) return p;
    }
  }
  throw TopologyError(to_string(c) + " is not a side of its edge " + to_string(e));
}

RotationId Dlfl::rotation_of(CornerId c) const {
  const VertexId v = corners_[c.idx].vertex;
  const RotationId first = vertices_[v.idx].first;
  if (!next_rotation(first).valid()) return first;
  CornerId x = c;
  do {
    for (RotationId r = first; r.valid(); r = next_rotation(r)) {
      if (rotations_[r.idx].corner == x) return r;
    }
    x = rot_next(x);
  } while (x != c);
  return RotationId{};
}

// ---------------------------------------------------------------- vertex operators

VertexId Dlfl::create_vertex(const Vec3& position) {
  const VertexId v = new_vertex();
  positions_[v.idx] = position;
  const CornerId c = new_corner(v);
  const FaceId f = new_face(c);
  corners_[c.idx].face = f;
  vertices_[v.idx].first = new_rotation(c);
  ++topology_version_;
  return v;
}

void Dlfl::delete_vertex(VertexId v) {
  require(v, "delete_vertex");
  const RotationId r = vertices_[v.idx].first;
  if (next_rotation(r).valid()) {
    throw TopologyError("delete_vertex: " + to_string(v) +
                        " has several rotations (call clean_rotations first)");
  }
  const CornerId c = rotations_[r.idx].corner;
  if (!is_point_sphere(c)) {
    throw TopologyError("delete_vertex: " + to_string(v) +
                        " still has edges (only a lone point sphere can be deleted)");
  }
  free_face(corners_[c.idx].face);
  free_corner(c);
  free_rotation(v, r);
  vertices_[v.idx].first = RotationId{};
  free_vertices_.push_back(v.idx);
  ++topology_version_;
}

// ---------------------------------------------------------------- labels

void Dlfl::set_bounding(FaceId f, bool bounding) {
  require(f, "set_bounding");
  bounding_[f.idx] = bounding ? 1 : 0;
}

bool Dlfl::is_bounding(FaceId f) const {
  require(f, "is_bounding");
  return bounding_[f.idx] != 0;
}

// ---------------------------------------------------------------- rotations

AddRotationResult Dlfl::add_rotation(VertexId v) {
  require(v, "add_rotation");
  const CornerId c = new_corner(v);
  const FaceId f = new_face(c);
  corners_[c.idx].face = f;
  const RotationId r = new_rotation(c);
  // Append so that the first rotation stays first (clean_rotations keeps it).
  set_next_rotation(last_rotation(v), r);
  ++topology_version_;
  return {r, c, f};
}

void Dlfl::clean_rotations(VertexId v) {
  require(v, "clean_rotations");
  std::vector<RotationId> point_spheres;
  std::size_t total = 0;
  for (RotationId r = vertices_[v.idx].first; r.valid(); r = next_rotation(r)) {
    ++total;
    if (is_point_sphere(rotations_[r.idx].corner)) point_spheres.push_back(r);
  }
  // When every rotation is a point sphere, the first one stays.
  const std::size_t keep = point_spheres.size() == total ? 1 : 0;
  for (std::size_t i = keep; i < point_spheres.size(); ++i) {
    const RotationId r = point_spheres[i];
    const CornerId c = rotations_[r.idx].corner;
    free_face(corners_[c.idx].face);
    free_corner(c);
    free_rotation(v, r);
  }
  if (point_spheres.size() > keep) ++topology_version_;
}

void Dlfl::move_rotation_anchor(CornerId gone, CornerId replacement) {
  const VertexId v = corners_[gone.idx].vertex;
  for (RotationId r = vertices_[v.idx].first; r.valid(); r = next_rotation(r)) {
    if (rotations_[r.idx].corner == gone) {
      rotations_[r.idx].corner = replacement;
      return;
    }
  }
}

}  // namespace bisturi
