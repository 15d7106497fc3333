// The blood's particles as one drawable solid (see blood_drops.h).

#include "blood_drops.h"

#include <algorithm>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/polygon_import.h"

namespace bisturi::runtime {

namespace {

constexpr std::array<glm::dvec3, 6> kAxes{glm::dvec3(1, 0, 0), glm::dvec3(-1, 0, 0),
                                          glm::dvec3(0, 1, 0), glm::dvec3(0, -1, 0),
                                          glm::dvec3(0, 0, 1), glm::dvec3(0, 0, -1)};

}  // namespace

BloodDrops::BloodDrops(std::size_t capacity, double radius_mm)
    : radius_mm_(radius_mm), capacity_(capacity) {
  PolygonMesh polygons;
  // The faces of an octahedron, counter-clockwise seen from outside.
  constexpr std::array<std::array<std::uint32_t, 3>, 8> kFaces{
      {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}}};
  for (std::size_t d = 0; d < capacity; ++d) {
    const auto base = static_cast<std::uint32_t>(polygons.positions.size());
    const glm::dvec3 centre(0.0, 0.0, static_cast<double>(d) * 4.0 * radius_mm);
    for (const glm::dvec3& a : kAxes)
      polygons.positions.push_back(centre + radius_mm * a);
    for (const auto& f : kFaces)
      polygons.add_face({base + f[0], base + f[1], base + f[2]});
  }
  ImportResult r = import_polygons(polygons, true);
  mesh_ = std::move(r.mesh);
  vertex_ = std::move(r.vertex_of_input);
  place({});
}

void BloodDrops::place(const std::vector<glm::dvec3>& centres_mm) {
  const std::size_t n = std::min(centres_mm.size(), capacity_);
  for (std::size_t d = 0; d < capacity_; ++d) {
    for (std::size_t k = 0; k < kAxes.size(); ++k) {
      const VertexId v = vertex_[6 * d + k];
      if (v.idx >= mesh_.vertex_capacity()) continue;
      mesh_.positions()[v.idx] =
          d < n ? centres_mm[d] + radius_mm_ * kAxes[k]
                : (n > 0 ? centres_mm[0] : glm::dvec3(0.0));  // collapsed: not drawn
    }
  }
}

}  // namespace bisturi::runtime
