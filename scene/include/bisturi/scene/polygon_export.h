#pragma once
// The faces of a Dlfl as a plain polygon list (for writers and renderers): every unlabelled face
// with at least three corners, in face order; labelled faces (holes) and point spheres are not
// polygons. Vertices are numbered densely in vertex-handle order.

#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi {

struct ExportedPolygons {
  PolygonMesh polygons;
  std::vector<FaceId> face_of_polygon;       ///< the DLFL face of each polygon
  std::vector<VertexId> vertex_of_position;  ///< the DLFL vertex of each position
};

ExportedPolygons export_polygons(const Dlfl& mesh);

/// The face property (std::uint8_t, 1: yes) marking faces that show a solid's inside, such as a
/// wound's walls: drawn in its interior colour.
inline constexpr const char* kInteriorFaces = "interior";

}  // namespace bisturi
