#pragma once
// The Euclidean distance field of a mask: for every voxel inside, the distance (world mm, the
// grid's own spacing per axis) from its centre to the nearest voxel centre outside; 0 outside.
// Exact, separable in three passes of lower parabola envelopes (Felzenszwalb and Huttenlocher,
// "Distance transforms of sampled functions", 2012), linear in the voxel count. The volume's
// border is not outside: a vessel cut by the border keeps its radius up to the border.

#include <cstdint>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Distance (mm) from each inside voxel (nonzero) to the nearest outside voxel; +infinity for
/// every voxel when there is no outside voxel. Throws InputError when values and dims differ.
[[nodiscard]] Grid<float> distance_to_outside(const Grid<std::uint8_t>& mask);

}  // namespace bisturi
