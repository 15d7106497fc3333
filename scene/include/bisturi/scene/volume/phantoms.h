#pragma once
// Analytic phantoms: volumes whose true surfaces are known exactly, for demos, benchmarks and
// the checks of the scan-to-solid pipeline. Each sample holds the signed distance in millimetres
// to the phantom's surface, positive inside (an exact distance for the sphere, shell, torus and
// tube; the gyroid's level-set value scaled to millimetres near its surface), so the surface is
// the isosurface at 0 and `inside` means value > 0, as extraction defines it.

#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

enum class PhantomShape {
  Sphere,      ///< radius a, centred
  Shell,       ///< a spherical shell: outer radius a, inner radius b (two closed surfaces)
  Torus,       ///< major radius a, minor radius b, axis along z
  TwoSpheres,  ///< two spheres of radius a, their surfaces b millimetres apart along x
  Tube,        ///< an infinite cylinder of radius a along z: it runs through the border
  Gyroid,      ///< sin x cos y + sin y cos z + sin z cos x with period a (mm): a dense surface
};

struct PhantomOptions {
  PhantomShape shape = PhantomShape::Sphere;
  std::array<std::int64_t, 3> dims{64, 64, 64};
  glm::dvec3 spacing{0.5};
  /// Shape parameters in millimetres (see PhantomShape); <= 0 picks a size that fits the volume.
  double a = 0.0;
  double b = 0.0;
};

/// The phantom volume; origin at 0 and identity direction, the shape centred in the volume.
/// Throws InputError for dims < 2, a non-positive spacing, or parameters that make no shape.
Volume make_phantom(const PhantomOptions& options);

/// "sphere", "shell", "torus", "two-spheres", "tube", "gyroid".
std::string_view to_string(PhantomShape shape);
/// The shape named by to_string(); InputError naming the valid names otherwise.
PhantomShape phantom_shape_from_string(std::string_view name);
std::vector<std::string> phantom_shape_names();

}  // namespace bisturi
