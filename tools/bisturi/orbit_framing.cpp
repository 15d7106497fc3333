// The orbit's framing (see orbit_framing.h).

#include "orbit_framing.h"

#include <algorithm>
#include <cmath>

#include <glm/geometric.hpp>

namespace bisturi::cli {

OrbitFraming frame_orbit(const glm::dvec3& lo, const glm::dvec3& hi, const render::EyeFov& fov,
                         double ipd_mm) {
  OrbitFraming f;
  f.centre = (lo + hi) * 0.5;
  const double radius = std::max(glm::length(hi - lo) * 0.5, 1e-6);
  const double tan_half = std::tan(static_cast<double>(fov.angle_up));
  f.distance_mm = radius / (tan_half * 0.66);
  // The eyes see the solid between distance - radius and distance + radius (the orbit rises a
  // quarter of the distance, the eyes sit off its axis): the range keeps a margin both ways.
  f.near_mm = std::max(f.distance_mm - 2.0 * radius, f.distance_mm * 0.05);
  f.far_mm = f.distance_mm + 4.0 * radius;
  // As far apart, for the distance, as a person's eyes looking at something a few decimetres off.
  f.ipd_mm = std::min(ipd_mm, 0.1 * f.distance_mm);
  return f;
}

}  // namespace bisturi::cli
