#include "bisturi/runtime/render/drape_mesh.h"

#include <algorithm>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"

namespace bisturi::render {

Dlfl drape_sheet(const glm::dvec3& lo_mm, const glm::dvec3& hi_mm, double below_mm, double margin,
                 std::size_t cells) {
  const double side = std::max(hi_mm.x - lo_mm.x, hi_mm.y - lo_mm.y);
  const double reach = margin * side;
  const double width = side + 2.0 * reach;
  const glm::dvec3 centre = 0.5 * (lo_mm + hi_mm);
  PolygonMesh sheet = grid_mesh(cells, cells, width / double(cells), false);
  for (Dlfl::Vec3& p : sheet.positions)
    p += Dlfl::Vec3(centre.x - 0.5 * width, centre.y - 0.5 * width, lo_mm.z - below_mm);
  return build_oriented_manifold(sheet);
}

}  // namespace bisturi::render
