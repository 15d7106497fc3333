#pragma once
// Where a label's surface closes over the last slice it has (its top or bottom: the slice beyond
// holds no inside sample at all). Shape-based interpolation has no outline to interpolate to
// there: the empty slice counts one slice spacing outside everywhere, so the middle of a wide
// last slice (far inside its outline) is carried most of the way to the empty slice, and two
// objects one empty slice apart bulge towards each other across it. Instead, each vertex on a
// crossed edge from such a slice to the empty one goes where a paraboloid cap over its region of
// the slice puts it: h (1 - (1 - d / r)^2) beyond the slice, with d the sample's in-slice
// distance to the outline, r the largest in its region (the region's "radius"), and h half the
// slice spacing: where an end between two slices lies on average. It meets the sides at the
// outline (d = 0) and is highest over the region's middle, as a convex end is.

#include <span>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Moves the vertices of a surface extracted from `field` (in-slice signed distances, positive
/// inside, slices along k) that lie on crossed k-edges into an empty slice, to the cap above.
void place_cap_vertices(std::span<Dlfl::Vec3> positions, const Grid<float>& field);

}  // namespace bisturi
