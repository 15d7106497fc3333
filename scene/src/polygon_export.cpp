#include "bisturi/scene/polygon_export.h"

namespace bisturi {

ExportedPolygons export_polygons(const Dlfl& mesh) {
  ExportedPolygons out;
  std::vector<std::uint32_t> index_of(mesh.vertex_capacity(), kInvalidIndex);
  for (std::uint32_t v = 0; v < mesh.vertex_capacity(); ++v) {
    if (!mesh.alive(VertexId(v))) continue;
    index_of[v] = static_cast<std::uint32_t>(out.polygons.positions.size());
    out.polygons.positions.push_back(mesh.position(VertexId(v)));
    out.vertex_of_position.emplace_back(v);
  }
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId face(f);
    if (!mesh.alive(face) || mesh.is_bounding(face)) continue;
    const CornerId start = mesh.first_corner(face);
    if (mesh.next(start) == start || mesh.next(mesh.next(start)) == start) continue;
    CornerId c = start;
    do {
      out.polygons.indices.push_back(index_of[mesh.vertex(c).idx]);
      c = mesh.next(c);
    } while (c != start);
    out.polygons.offsets.push_back(static_cast<std::uint32_t>(out.polygons.indices.size()));
    out.face_of_polygon.push_back(face);
  }
  return out;
}

}  // namespace bisturi
