#include "solid_boundary.h"

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
