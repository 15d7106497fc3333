#include "solid_boundary.h"

#include "bisturi/scene/polygon_export.h"

namespace bisturi::render {

void SolidBoundary::rebuild(const Dlfl& mesh) {
  loops_.clear();
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId face{f};
    if (!mesh.alive(face) || !mesh.is_bounding(face)) continue;
    std::vector<std::uint32_t> loop;
    const CornerId first = mesh.first_corner(face);
    CornerId c = first;
    do {
      loop.push_back(mesh.vertex(c).idx);
      c = mesh.next(c);
    } while (c != first);
    loops_.push_back(std::move(loop));
  }
  holes_ = loops_.size();
  // A wound closed by walls is an opening too: its mouth, the walls' vertices on the outside
  // surface as well, is the portal through which what lies inside shows.
  if (mesh.face_properties().has(kInteriorFaces)) {
    const auto& interior = mesh.face_properties().get<std::uint8_t>(kInteriorFaces);
    std::vector<std::uint8_t> at(mesh.vertex_capacity(), 0);  // bit 0: on a wall, 1: outside
    for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
      const FaceId face{f};
      if (!mesh.alive(face) || mesh.is_bounding(face)) continue;
      const std::uint8_t kind = interior[face] ? 1u : 2u;
      // The corners walked in place: a list of each face's vertices would cost an allocation
      // for every face of a 20k-vertex drawn surface at each cut.
      const CornerId first = mesh.first_corner(face);
      CornerId c = first;
      do {
        at[mesh.vertex(c).idx] = static_cast<std::uint8_t>(at[mesh.vertex(c).idx] | kind);
        c = mesh.next(c);
      } while (c != first);
    }
    std::vector<std::uint32_t> mouth;
    for (std::uint32_t v = 0; v < at.size(); ++v)
      if (at[v] == 3u) mouth.push_back(v);
    if (!mouth.empty()) loops_.push_back(std::move(mouth));
  }
  topology_version_ = mesh.topology_version();
  refit(mesh);
}

void SolidBoundary::refit(const Dlfl& mesh) {
  portals_.assign(loops_.size(), Aabb{});
  for (std::size_t i = 0; i < loops_.size(); ++i) {
    for (const std::uint32_t v : loops_[i])
      portals_[i].extend(mesh.position(VertexId{v}));
  }
}

}  // namespace bisturi::render
