// A scene file's solids for `bisturi render` (see render_scene.h).

#include "render_scene.h"

#include <optional>
#include <stdexcept>
#include <utility>

#include <glm/vec3.hpp>

#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/units.h"

namespace bisturi::cli {

namespace {

render::Material material_of(const std::array<double, 3>& rgb) {
  render::Material m;
  m.colour =
      glm::vec3(static_cast<float>(rgb[0]), static_cast<float>(rgb[1]), static_cast<float>(rgb[2]));
  return m;
}

/// `mesh` cut along the straight path from `from_mm` to `to_mm` (its points snapped to the
/// surface by the cut itself, as a session's blade points are).
Dlfl incised(Dlfl mesh, const std::array<double, 3>& from_mm, const std::array<double, 3>& to_mm) {
  sim::SoftBody body(std::move(mesh), sim::Material{});
  std::vector<glm::dvec3> points;
  constexpr int kPoints = 24;
  for (int i = 0; i <= kPoints; ++i) {
    const double t = static_cast<double>(i) / kPoints;
    const glm::dvec3 p = glm::dvec3(from_mm[0], from_mm[1], from_mm[2]) * (1.0 - t) +
                         glm::dvec3(to_mm[0], to_mm[1], to_mm[2]) * t;
    points.push_back(sim::scene_to_sim(p));
  }
  (void)sim::cut_surface(body, points);
  body.write_positions_to_scene();
  return body.mesh();
}

}  // namespace

std::vector<SceneSolid> scene_solids(const std::string& scene_file, bool incision) {
  const runtime::SceneDescription scene = runtime::read_scene_file(scene_file);
  std::vector<runtime::BuiltSolid> built = runtime::build_solids(scene);
  std::vector<SceneSolid> out;
  for (std::size_t b = 0; b < built.size(); ++b) {
    const runtime::SolidDescription& d = scene.solids[b];
    std::optional<Dlfl> drawn = runtime::build_drawn_surface(d, scene_file);
    Dlfl mesh = drawn ? std::move(*drawn) : std::move(built[b].mesh);
    if (incision && b == 0) {
      if (!scene.procedure)
        throw std::invalid_argument(scene_file + ": --incision needs the scene's [procedure] cut");
      mesh = incised(std::move(mesh), scene.procedure->cut_from_mm, scene.procedure->cut_to_mm);
    }
    out.push_back({d.name, std::move(mesh), material_of(d.material.colour), -1});
  }
  for (std::size_t b = 0; b < built.size(); ++b) {
    for (const runtime::SolidDescription& in : scene.solids[b].inner)
      out.push_back({in.name, runtime::build_solid(in, scene_file), material_of(in.material.colour),
                     static_cast<std::int32_t>(b)});
  }
  return out;
}

}  // namespace bisturi::cli
