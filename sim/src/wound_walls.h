#pragma once
// Internal to sim/: the walls of an incision made inside a surface (cutting.cpp). The opening
// the cut leaves (a labelled face: one lip, the far end, the other lip) is closed by two walls
// that meet at a floor line as deep as the blade went, so the wound is a notch in a closed
// solid: its walls are faces of the solid, marked interior (kInteriorFaces) for drawing.

#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

/// Closes the incision along `path` (its ends not opened) whose far lip is `right` (right[i]
/// the copy of path[i], for 0 < i < path.size() - 1): a floor vertex under each opened pair,
/// at `floor_m` (world) and `floor_rest_m` (rest), joined to both lips and to its neighbours.
/// Returns the floor vertices.
std::vector<VertexId> close_incision(SoftBody& body, const std::vector<VertexId>& path,
                                     const std::vector<VertexId>& right,
                                     std::span<const glm::dvec3> floor_m,
                                     std::span<const glm::dvec3> floor_rest_m);

}  // namespace bisturi::sim
