#pragma once
// Simple meshes for instruments: a capsule (a shaft with round ends) along +z from the origin,
// outward-oriented, as a DLFL ready for the renderer.

#include <cstddef>

#include "bisturi/scene/dlfl.h"

namespace bisturi::render {

/// A capsule of `radius` whose axis runs from (0, 0, 0) to (0, 0, length) (millimetres).
Dlfl capsule_solid(double radius, double length, std::size_t segments = 24, std::size_t rings = 8);

}  // namespace bisturi::render
