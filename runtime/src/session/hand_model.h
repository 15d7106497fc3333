#pragma once
// Where a glove's fingertips are, from the hand's pose and its finger joints, so that each finger
// actuator can render that finger's own contact with the tissue.
//
// The model (scene frame, millimetres): the glove's end effector is the instrument's tip and the
// hand holds the instrument's shaft at its far end, `shaft_mm` up the hand's +z axis (the shaft
// runs along +z from the tip, as the renderer draws it). From there the five fingers (thumb,
// index, middle, ring, little) hang down the shaft (-z), spread across the hand's x axis, and curl
// towards the palm (+y) with their joints' flexion: each finger has `joints / 5` joints, the
// angles add up along it (radians, 0 = straight). A straight finger reaches 60-85 % of the way
// down the shaft, so the fingers meet the tissue only when the hand comes close to it.

#include <array>
#include <cstddef>
#include <span>

#include <glm/gtc/quaternion.hpp>
#include <glm/vec3.hpp>

namespace bisturi::runtime {

constexpr std::size_t kHandFingers = 5;

/// Fingertip positions (scene frame, mm) for the tip at tip_mm, the hand's orientation and its
/// finger joint angles (finger after finger; a glove with fewer joints than fingers leaves the
/// remaining fingers straight).
std::array<glm::dvec3, kHandFingers> fingertips_mm(const glm::dvec3& tip_mm,
                                                    const glm::dquat& hand, double shaft_mm,
                                                    std::span<const double> joints_rad);

}  // namespace bisturi::runtime
