#pragma once
// The drape the organs lie on: a flat sheet under the solids, as the sterile drapes round an
// operating field are. It gives the field a floor that the lamp lights and the blood pools on
// (the blood's tray is at the same height: sim/blood.h), where the solids would otherwise float
// in a void.

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"

namespace bisturi::render {

/// A horizontal sheet `below_mm` under the box [lo_mm, hi_mm] (world millimetres, z up),
/// reaching `margin` times the box's larger horizontal side past it each way, in `cells` x
/// `cells` quads (small quads: no huge triangle crosses an eye's near plane), facing up.
Dlfl drape_sheet(const glm::dvec3& lo_mm, const glm::dvec3& hi_mm, double below_mm = 2.0,
                 double margin = 1.0, std::size_t cells = 24);

}  // namespace bisturi::render
