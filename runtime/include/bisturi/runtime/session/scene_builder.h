#pragma once
// Builds the solids of a SceneDescription at start-up: phantom or volume -> isosurface (marching
// cubes into the DLFL; a label of a label map through the smooth label surface of
// label_surface.h) -> decimation -> Taubin smoothing -> offset; mesh files through the polygon
// import. One mesh per solid for the tissue model, drawn too unless the solid asks for a finer
// drawn surface ([solids.drawn]: build_drawn_surface). Deterministic: a live session and its
// replay build identical solids.

#include <cstddef>
#include <functional>
#include <optional>
#include <string_view>
#include <vector>

#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/scene/dlfl.h"

namespace bisturi::runtime {

struct BuiltSolid {
  const SolidDescription* description = nullptr;  ///< into the scene it was built from
  Dlfl mesh;                                      ///< world millimetres, compacted
  double build_ms = 0.0;
  const SceneDescription* scene = nullptr;  ///< the scene it was built from (its [procedure])
};

/// (solid name, stage, done, total) while a solid is built.
using BuildProgress =
    std::function<void(std::string_view solid, std::string_view stage, std::size_t, std::size_t)>;

/// Builds one solid. Throws SceneFileError (naming the scene file and the solid) when the source
/// gives no surface; InputError from the readers for bad files.
Dlfl build_solid(const SolidDescription& solid, const std::string& scene_name,
                 const BuildProgress& progress = {});

/// The solid's drawn surface, when it asks for one finer than its simulated one: the same source
/// with its [solids.drawn] settings. None without them.
std::optional<Dlfl> build_drawn_surface(const SolidDescription& solid,
                                        const std::string& scene_name,
                                        const BuildProgress& progress = {});

/// Builds every solid of `scene`, in order.
std::vector<BuiltSolid> build_solids(const SceneDescription& scene,
                                     const BuildProgress& progress = {});

}  // namespace bisturi::runtime
