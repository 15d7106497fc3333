// compact(): renumbers every element densely, in the order of the old indices, so that handles
// are again 0..n-1 and the free lists are empty. Attribute arrays are renumbered alongside.

#include "bisturi/scene/dlfl.h"

#include <algorithm>

namespace bisturi {

namespace {

/// new_index[old] for live slots (kInvalidIndex for dead ones); returns the live count.
template <class Alive>
std::size_t dense_numbering(std::size_t capacity, Alive alive, std::vector<std::uint32_t>& out) {
  out.assign(capacity, kInvalidIndex);
  std::uint32_t next = 0;
  for (std::size_t i = 0; i < capacity; ++i) {
    if (alive(i)) out[i] = next++;
  }
  return next;
}

template <class Records>
void move_records(Records& records, const std::vector<std::uint32_t>& new_index, std::size_t live) {
  Records out(live);
  for (std::size_t i = 0; i < records.size(); ++i) {
    if (new_index[i] != kInvalidIndex) out[new_index[i]] = records[i];
  }
  records = std::move(out);
}

template <class Tag>
Handle<Tag> remap(Handle<Tag> h, const std::vector<std::uint32_t>& new_index) {
  return h.valid() ? Handle<Tag>(new_index[h.idx]) : h;
}

}  // namespace

void Dlfl::compact() {
  std::vector<std::uint32_t> vmap, cmap, fmap, emap, rmap;
  const std::size_t nv = dense_numbering(
      vertices_.size(), [&](std::size_t i) { return vertices_[i].first.valid(); }, vmap);
  const std::size_t nc = dense_numbering(
      corners_.size(), [&](std::size_t i) { return corners_[i].vertex.valid(); }, cmap);
  const std::size_t nf = dense_numbering(
      faces_.size(), [&](std::size_t i) { return faces_[i].first.valid(); }, fmap);
  const std::size_t ne = dense_numbering(
      edges_.size(), [&](std::size_t i) { return edges_[i].a.valid(); }, emap);
  const std::size_t nr = dense_numbering(
      rotations_.size(), [&](std::size_t i) { return rotations_[i].corner.valid(); }, rmap);

  for (auto& c : corners_) {
    if (!c.vertex.valid()) continue;
    c = CornerRecord{remap(c.vertex, vmap), remap(c.face, fmap), remap(c.next, cmap),
                     remap(c.prev, cmap), remap(c.edge, emap)};
  }
  for (auto& f : faces_)
    f.first = remap(f.first, cmap);
  for (auto& e : edges_)
    e = CornerPair{remap(e.a, cmap), remap(e.b, cmap)};
  for (auto& v : vertices_)
    v.first = remap(v.first, rmap);
  for (auto& r : rotations_)
    r = RotationRecord{remap(r.corner, cmap)};
  for (auto& [from, to] : rotation_links_) {
    from = rmap[from];
    to = rmap[to];
  }
  std::sort(rotation_links_.begin(), rotation_links_.end());
  for (auto& [edge, pairs] : extra_pairs_) {
    edge = emap[edge];
    for (auto& p : pairs)
      p = CornerPair{remap(p.a, cmap), remap(p.b, cmap)};
  }
  // Dense numbering keeps the old order, so extra_pairs_ stays sorted by edge.

  move_records(corners_, cmap, nc);
  move_records(faces_, fmap, nf);
  move_records(edges_, emap, ne);
  move_records(vertices_, vmap, nv);
  move_records(rotations_, rmap, nr);
  move_records(positions_, vmap, nv);
  move_records(bounding_, fmap, nf);

  vertex_props_.renumber(vmap, nv);
  corner_props_.renumber(cmap, nc);
  face_props_.renumber(fmap, nf);
  edge_props_.renumber(emap, ne);

  free_vertices_.clear();
  free_corners_.clear();
  free_faces_.clear();
  free_edges_.clear();
  free_rotations_.clear();
  ++topology_version_;
}

}  // namespace bisturi
