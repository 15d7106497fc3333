// A solid's topology for the render thread (see session_snapshot.h).

#include "session_snapshot.h"

#include "bisturi/scene/polygon_export.h"

namespace bisturi::runtime {

std::shared_ptr<const Topology> make_topology(const Dlfl& mesh) {
  auto t = std::make_shared<Topology>();
  t->version = mesh.topology_version();
  ExportedPolygons e = export_polygons(mesh);
  t->polygons = std::move(e.polygons);
  t->slot_of_position.reserve(e.vertex_of_position.size());
  for (VertexId v : e.vertex_of_position)
    t->slot_of_position.push_back(v.idx);
  return t;
}

}  // namespace bisturi::runtime
