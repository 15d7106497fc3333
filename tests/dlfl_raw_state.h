#pragma once
// Test support: a bit-exact picture of a Dlfl's raw storage, for checking that a refused or
// undone operation left everything as it was.

#include <cstdint>
#include <vector>

#include "bisturi/scene/dlfl.h"

namespace bisturi::testing_support {

/// Every raw record, free list, label, position and the topology version: a refused call must
/// leave all of it bit-identical.
struct RawState {
  std::vector<std::uint32_t> words;
  std::vector<std::uint8_t> labels;
  std::vector<double> coordinates;
  std::uint64_t version = 0;
  std::vector<std::size_t> sizes;
  bool operator==(const RawState&) const = default;
};

inline RawState raw_state(const Dlfl& m) {
  RawState s;
  for (const auto& c : m.corner_records()) {
    s.words.insert(s.words.end(), {c.vertex.idx, c.face.idx, c.next.idx, c.prev.idx, c.edge.idx});
  }
  for (const auto& f : m.face_records())
    s.words.push_back(f.first.idx);
  for (const auto& e : m.edge_records())
    s.words.insert(s.words.end(), {e.a.idx, e.b.idx});
  for (const auto& v : m.vertex_records())
    s.words.push_back(v.first.idx);
  for (const auto& r : m.rotation_records())
    s.words.push_back(r.corner.idx);
  for (const auto& [from, to] : m.rotation_links())
    s.words.insert(s.words.end(), {from, to});
  for (const auto& [edge, pairs] : m.extra_pair_lists()) {
    s.words.push_back(edge);
    for (const auto& p : pairs)
      s.words.insert(s.words.end(), {p.a.idx, p.b.idx});
  }
  for (const auto* list :
       {&m.free_list(VertexTag{}), &m.free_list(CornerTag{}), &m.free_list(FaceTag{}),
        &m.free_list(EdgeTag{}), &m.free_list(RotationTag{})}) {
    s.words.push_back(static_cast<std::uint32_t>(list->size()));
    s.words.insert(s.words.end(), list->begin(), list->end());
  }
  s.labels.assign(m.bounding_labels().begin(), m.bounding_labels().end());
  for (const auto& p : m.positions())
    s.coordinates.insert(s.coordinates.end(), {p.x, p.y, p.z});
  s.version = m.topology_version();
  s.sizes = {m.num_vertices(), m.num_corners(), m.num_faces(), m.num_edges(), m.num_rotations()};
  return s;
}

}  // namespace bisturi::testing_support
