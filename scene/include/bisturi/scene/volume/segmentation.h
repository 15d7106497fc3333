#pragma once
// Segmentation of volumes (seed section 2.2.1): thresholds and CT windows, connected components,
// region growing from a seed and 3-D split-and-merge over the BONO octree. Every result keeps the
// VolumeGeometry of its input. Masks: 0 outside, 1 (any nonzero when read) inside.

#include <array>
#include <cstdint>
#include <vector>

#include "bisturi/scene/volume/bono_octree.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// A closed interval of values [lo, hi].
struct IntensityRange {
  float lo = 0;
  float hi = 0;
};

/// The range of a CT display window written as centre (level) and width: [c - w/2, c + w/2].
/// Throws InputError for a negative or non-finite width or a non-finite centre.
[[nodiscard]] IntensityRange window_range(float centre, float width);

/// 1 where lo <= value <= hi, else 0 (NaN is outside). Throws InputError when lo > hi, a bound
/// is NaN, or the values do not match the dims.
[[nodiscard]] Grid<std::uint8_t> threshold(const Volume& volume, float lo, float hi);
[[nodiscard]] inline Grid<std::uint8_t> threshold(const Volume& volume, IntensityRange range) {
  return threshold(volume, range.lo, range.hi);
}

/// Six: face neighbours. TwentySix: face, edge and corner neighbours.
enum class Connectivity { Six, TwentySix };

struct ComponentOptions {
  /// Components with fewer voxels become background (0) and take no label.
  std::int64_t min_voxels = 0;
};

struct ComponentStats {
  std::uint32_t label = 0;
  std::int64_t voxel_count = 0;
  /// Bounding box in sample indices.
  BonoBox bounds;
  /// The component's first voxel in memory order (i fastest).
  std::array<std::int64_t, 3> first_voxel{};
};

struct Components {
  /// 0: background; 1..label_count: components.
  LabelVolume labels;
  /// stats[l - 1] describes label l.
  std::vector<ComponentStats> stats;
};

/// Connected components of the nonzero voxels of `mask`. Labels 1..n are ordered by each
/// component's first voxel in memory order (i fastest, then j, then k), after dropping those
/// smaller than options.min_voxels. Linear time (runs along i + union-find).
[[nodiscard]] Components label_components(const Grid<std::uint8_t>& mask, Connectivity connectivity,
                                          const ComponentOptions& options = {});

/// The voxels with lo <= value <= hi connected to `seed` (i, j, k) (e.g. a contrast-filled
/// vessel): 1 inside, 0 outside. Throws InputError naming the seed (and its value) when the seed
/// is outside the volume or its value is outside [lo, hi].
[[nodiscard]] Grid<std::uint8_t> region_grow(const Volume& volume, std::array<std::int64_t, 3> seed,
                                             float lo, float hi, Connectivity connectivity);

struct SplitMergeOptions {
  /// A region is homogeneous when max - min <= tolerance (>= 0).
  float tolerance = 0;
  /// Regions smaller than this (in voxels) after merging join the face-adjacent region of
  /// closest mean (ignoring the tolerance). 1 keeps every region.
  std::int64_t min_region_voxels = 1;
};

/// 3-D split-and-merge (Horowitz-Pavlidis over the BONO octree, seed section 2.2.1): BONO nodes
/// are split until homogeneous or a single voxel (a node whose children are all homogeneous and
/// that is homogeneous itself stays whole), then face-adjacent regions are merged (union-find,
/// voxel pairs visited in memory order) while the merged region stays homogeneous, then small
/// regions are absorbed. Every voxel gets a label; labels 1..n follow each region's first voxel
/// in memory order. Throws InputError for a negative or NaN tolerance or a bad volume.
[[nodiscard]] LabelVolume split_and_merge(const Volume& volume,
                                          const SplitMergeOptions& options = {});

/// 1 inside `label`, 0 elsewhere (extract the surface at iso 0.5).
[[nodiscard]] Grid<float> label_indicator(const LabelVolume& labels, std::uint32_t label);
/// label_indicator as a Volume with the labels' geometry (modality and source empty).
[[nodiscard]] Volume label_indicator_volume(const LabelVolume& labels, std::uint32_t label);

}  // namespace bisturi
