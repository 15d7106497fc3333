#pragma once
// Step 1 of label surfaces (label_surface.h): the field marching cubes runs on, each sample's
// signed in-slice distance to the label's outline, and the slices the caps read.

#include <cstddef>
#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Samples further apart along one axis than along another by this factor or more are thicker:
/// the slices are taken across the thickest axis (label_surface.cpp), and maps whose slices are
/// thicker than their in-slice samples get the sharp rounds and more fit sweeps
/// (label_smoothing.cpp).
constexpr double kThicker = 1.2;

/// Each sample's signed in-slice distance (mm) to the outline of `mask`'s inside, positive
/// inside. A slice without inside (or outside) samples, or one `wanted` (if given) does not
/// hold, counts as one slice spacing away; slices of one kind (most of a map around a label)
/// are not transformed.
Grid<float> signed_slice_distances(std::span<const std::uint8_t> mask, const VolumeGeometry& g,
                                   const std::vector<std::uint8_t>* wanted);

/// The slices where a 4-connected region of `mask`'s inside ends (none of its samples is inside
/// in the next slice, or in the one before), with the two slices either side: all that the caps
/// over those ends read (label_caps.h).
std::vector<std::uint8_t> slices_around_ends(const std::vector<std::uint8_t>& mask,
                                             const VolumeGeometry& g);

/// The field marching cubes runs on for `label` (shape-based interpolation, label_field.cpp);
/// `inside` gets the label's sample count and `indicator` the field's sign: the band the
/// smoothing keeps vertices in.
Grid<float> label_field(const Grid<float>& labels, float label, std::size_t& inside,
                        Grid<float>& indicator);

}  // namespace bisturi
