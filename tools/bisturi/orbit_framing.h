#pragma once
// Where `bisturi render` puts its orbiting eyes for a solid of any size and units: far enough that
// the solid fills about two thirds of the field of view, with a depth range and an eye separation
// that follow the solid's size (a fixed 10 mm near plane and 64 mm between the eyes would miss a
// 0.1 mm part entirely, and unit-scale meshes are often that small in millimetres).

#include <glm/vec3.hpp>

#include "bisturi/runtime/render/headset.h"

namespace bisturi::cli {

struct OrbitFraming {
  glm::dvec3 centre{0.0};
  double distance_mm = 0.0;  ///< from the centre to the eyes' midpoint
  double near_mm = 0.0;
  double far_mm = 0.0;
  double ipd_mm = 0.0;
};

/// The framing of a box lo..hi (mm) for eyes with `fov`, at most `ipd_mm` apart.
OrbitFraming frame_orbit(const glm::dvec3& lo, const glm::dvec3& hi, const render::EyeFov& fov,
                         double ipd_mm);

}  // namespace bisturi::cli
