#include "bisturi/runtime/render/instrument_mesh.h"

#include <cmath>
#include <numbers>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi::render {

Dlfl capsule_solid(double radius, double length, std::size_t segments, std::size_t rings) {
  if (!(radius > 0.0) || !(length >= 0.0) || segments < 3 || rings < 1) {
    throw InputError("capsule_solid: needs radius > 0, length >= 0, segments >= 3, rings >= 1");
  }
  PolygonMesh mesh;
  // Rings from the bottom pole to the top pole: `rings` on the lower half sphere (at z = 0), the
  // same on the upper one (at z = length); the shaft joins the two equators.
  const auto add_ring = [&](double phi, double z0) {
    const double rho = radius * std::cos(phi);
    const double z = z0 + radius * std::sin(phi);
    for (std::size_t j = 0; j < segments; ++j) {
      const double theta =
          2.0 * std::numbers::pi * static_cast<double>(j) / static_cast<double>(segments);
      mesh.positions.push_back({rho * std::cos(theta), rho * std::sin(theta), z});
    }
  };
  mesh.positions.push_back({0.0, 0.0, -radius});  // bottom pole: vertex 0
  const double step = std::numbers::pi / 2.0 / static_cast<double>(rings);
  for (std::size_t i = 1; i <= rings; ++i)
    add_ring(-std::numbers::pi / 2.0 + step * static_cast<double>(i), 0.0);
  for (std::size_t i = 0; i < rings; ++i)
    add_ring(step * static_cast<double>(i), length);
  const auto top = static_cast<std::uint32_t>(mesh.positions.size());
  mesh.positions.push_back({0.0, 0.0, length + radius});
  const std::size_t ring_count = 2 * rings;
  const auto at = [&](std::size_t ring, std::size_t j) {
    return static_cast<std::uint32_t>(1 + ring * segments + j % segments);
  };
  for (std::size_t j = 0; j < segments; ++j)
    mesh.add_face({0u, at(0, j + 1), at(0, j)});
  for (std::size_t r = 0; r + 1 < ring_count; ++r) {
    for (std::size_t j = 0; j < segments; ++j) {
      mesh.add_face({at(r, j), at(r, j + 1), at(r + 1, j + 1), at(r + 1, j)});
    }
  }
  for (std::size_t j = 0; j < segments; ++j) {
    mesh.add_face({at(ring_count - 1, j), at(ring_count - 1, j + 1), top});
  }
  return build_oriented_manifold(mesh);
}

}  // namespace bisturi::render
