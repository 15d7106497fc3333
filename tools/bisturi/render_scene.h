#pragma once
// What `bisturi render` draws from a scene file: each solid as a session draws it (its finer
// drawn surface where it has one), in its material's colour, and the structures inside it
// ([[solids.inner]]) enclosed by it; with `incision`, the first solid cut along the scene's
// [procedure] cut first, so its structures are seen through the incision as a portal.

#include <cstdint>
#include <string>
#include <vector>

#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/scene/dlfl.h"

namespace bisturi::cli {

struct SceneSolid {
  std::string name;
  Dlfl mesh;  ///< world millimetres
  render::Material material;
  std::int32_t enclosed_by = -1;  ///< index of the solid it lies inside
};

/// Throws SceneFileError and the readers' errors for a bad scene, std::invalid_argument for an
/// incision in a scene without a [procedure], sim::CutError when it gives no path on the first
/// solid.
std::vector<SceneSolid> scene_solids(const std::string& scene_file, bool incision);

}  // namespace bisturi::cli
