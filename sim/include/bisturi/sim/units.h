#pragma once
// The one seam between scene units and simulation units.
//
// scene/ stores positions in world millimetres (the volume's frame); sim/ works in SI units:
// metres, kilograms, newtons, seconds, with the unit in names where it could be ambiguous. Every
// conversion between the two goes through these functions (SoftBody construction reads a Dlfl,
// SoftBody::write_positions_to_scene() writes it back, cutting creates vertices in millimetres).
// The frame is the same: no rotation or offset, only the scale.

#include <glm/vec3.hpp>

namespace bisturi::sim {

inline constexpr double kMetresPerMillimetre = 1e-3;
inline constexpr double kMillimetresPerMetre = 1e3;

inline glm::dvec3 scene_to_sim(const glm::dvec3& millimetres) {
  return millimetres * kMetresPerMillimetre;
}
inline glm::dvec3 sim_to_scene(const glm::dvec3& metres) {
  return metres * kMillimetresPerMetre;
}

}  // namespace bisturi::sim
