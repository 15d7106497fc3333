#pragma once
// Where a label's surface closes over the last slice of a region (its top or bottom: none of the
// region's samples is inside in the slice beyond, which may be empty or hold other objects).
// Shape-based interpolation has no outline of the region to interpolate to there: the slice
// beyond counts as far outside as the nearest other outline, or one slice spacing where it is
// empty, so the middle of a wide last slice (far inside its outline) is carried most of the way
// to the slice beyond, and two objects one empty slice apart bulge towards each other across it.
// Instead, each vertex on a crossed edge from such a region to the slice beyond goes where a
// cap over the region puts it, by where the sample lies between the region's middle and its
// outline (its in-slice distance to the outline, against the largest in its region, the
// region's "radius", and its own local width: label_caps.cpp, section_share) and by how the
// region's area narrows over the last three slices (cap_height). It meets the sides at the outline
// and is highest over the region's middle, as a convex end is. A part of a region narrower than its
// middle (a crescent's arm, the top of a ring's tube, a saddle where the slice beyond holds the
// region on either side but not over it) ends under a cap of its own width: the radius of the
// widest in-slice disc round the sample, found by walking up the distance from the sample. A tube
// lying across the slices, whose top runs along the last slice and rises into the slice beyond
// only further along, has its top over a sample placed by its local widths: a round section
// through its last two slices, or about its one slice where it is only that high, or fitted
// over its last three where it is higher (the top of a ring's tube at even sampling).

#include <span>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Which vertices on crossed k-edges place_vertices_across_slices moves.
enum class AcrossSlices {
  /// Out of a region's (or a narrow part's) last slice, to the cap above; out of a region that
  /// narrows into the slice beyond, to where its squared width reaches the sample.
  All,
  /// Only out of a region's last slice (the whole region ends there), and only where the cap
  /// lies further out than the vertex does: the tip of a shape along an axis sampled as finely
  /// as the slices bulges past the midpoint marching cubes puts its vertex at. The field need
  /// hold distances only in the two slices either side of such ends.
  EndsFurtherOut,
};

/// Moves the vertices of a surface extracted from `field` (in-slice signed distances, positive
/// inside, slices along k) that lie on crossed k-edges: out of a region's last slice, to the cap
/// above; out of a region that narrows into the slice beyond, to where its squared width (not
/// its width, as the linear interpolation of the distances has it) reaches the sample, as under
/// a rounded end.
void place_vertices_across_slices(std::span<Dlfl::Vec3> positions, const Grid<float>& field,
                                  AcrossSlices which = AcrossSlices::All);

}  // namespace bisturi
