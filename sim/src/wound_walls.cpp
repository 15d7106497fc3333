// The walls of an incision inside a surface (see wound_walls.h).
#include "wound_walls.h"

#include <cstdint>

#include "bisturi/sim/cutting.h"
#include "bisturi/sim/errors.h"
#include "vertex_corners.h"

namespace bisturi::sim {
namespace {

/// v's corner in a labelled face (the opening), or none.
CornerId opening_corner(const Dlfl& mesh, VertexId v) {
  CornerId found;
  for_each_corner(mesh, v, [&](CornerId c) {
    if (!found.valid() && mesh.is_bounding(mesh.face(c))) found = c;
  });
  return found;
}

/// u's corner in a face that also holds w, and w's corner there.
std::pair<CornerId, CornerId> shared_face(const Dlfl& mesh, VertexId u, VertexId w) {
  std::pair<CornerId, CornerId> out;
  for_each_corner(mesh, u, [&](CornerId c) {
    if (out.first.valid()) return;
    for (CornerId o = mesh.next(c); o != c; o = mesh.next(o)) {
      if (mesh.vertex(o) != w) continue;
      out = {c, o};
      return;
    }
  });
  return out;
}

}  // namespace

std::vector<VertexId> close_incision(SoftBody& body, const std::vector<VertexId>& path,
                                     const std::vector<VertexId>& right,
                                     std::span<const glm::dvec3> floor_m,
                                     std::span<const glm::dvec3> floor_rest_m) {
  Dlfl& mesh = body.mesh_for_edit();
  const std::size_t k = path.size() - 1;
  InsertEdgeOptions no_check;
  no_check.check_label_orientation = false;
  std::vector<VertexId> floor;
  // A chain lip - floor - lip across the opening under each opened pair: each splits off the
  // part of the opening before it.
  for (std::size_t i = 1; i < k; ++i) {
    const VertexId b = mesh.create_vertex(floor_m[i - 1]);
    body.ensure_capacity();
    body.set_position(b, floor_m[i - 1]);
    body.set_rest_position(b, floor_rest_m[i - 1]);
    body.set_velocity(b, body.velocity(path[i]));
    floor.push_back(b);
    const CornerId left = opening_corner(mesh, path[i]);
    if (!left.valid()) throw CutError("cut: no opening at the lip to close");
    const InsertEdgeResult joined =
        mesh.insert_edge(left, mesh.rotation_corner(mesh.first_rotation(b)), no_check);
    mesh.set_bounding(mesh.face(joined.side12), true);
    const CornerId far = opening_corner(mesh, right[i]);
    if (!far.valid()) throw CutError("cut: no opening at the far lip to close");
    (void)mesh.insert_edge(mesh.rotation_corner(mesh.first_rotation(b)), far, no_check);
  }
  // Between two chains a face of six corners (two lips, two floor vertices, two far lips): the
  // floor edge makes two quads, one on each wall.
  for (std::size_t i = 0; i + 1 < floor.size(); ++i) {
    const auto [a, b] = shared_face(mesh, floor[i], floor[i + 1]);
    if (a.valid()) (void)mesh.insert_edge(a, b, no_check);
  }
  // Every face round the floor is a wall: real, and the tissue's inside.
  auto& interior = mesh.face_properties().has(kInteriorFaces)
                       ? mesh.face_properties().get<std::uint8_t>(kInteriorFaces)
                       : mesh.face_properties().add<std::uint8_t>(kInteriorFaces, 0);
  for (const VertexId b : floor)
    for_each_corner(mesh, b, [&](CornerId c) {
      mesh.set_bounding(mesh.face(c), false);
      interior[mesh.face(c)] = 1;
    });
  return floor;
}

}  // namespace bisturi::sim
