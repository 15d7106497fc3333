#pragma once
// The stages of `bisturi pipeline` that are more than one library call: the vessel's mask from
// the plan's segmentation, the field its surface is extracted from, the profile plot.

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

#include "bisturi/scene/vessel/vessel_sections.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume.h"
#include "pipeline_plan.h"

namespace bisturi::cli {

struct VesselMask {
  Grid<std::uint8_t> mask;  ///< the one object: 1 inside
  std::size_t voxels = 0;
  std::size_t objects_in_range = 0;  ///< objects the range held (without a seed)
  std::string how;                   ///< "seed", "largest object", "label"
};

/// The vessel's voxels as the plan says. Throws std::runtime_error naming the reason (a seed
/// outside the volume or the range, an empty range, a missing label).
VesselMask segment_vessel(const Volume& volume, const PipelinePlan& plan);

/// The grid and options to extract the vessel's surface from: for a range, the scan itself (the
/// wall where the value crosses the range's low end, cubic placement) with everything farther
/// than three voxels from the vessel pushed below it; for a label, the label's indicator at 0.5.
struct SurfaceField {
  Grid<float> field;
  IsoSurfaceOptions iso;
};
SurfaceField surface_field(const Volume& volume, const VesselMask& vessel,
                           const PipelinePlan& plan);

/// Mean diameter against distance along the centreline, one line per branch.
void write_profile_png(const std::filesystem::path& file, const std::string& title,
                       const std::vector<VesselSection>& sections, std::size_t branches,
                       double step_mm);

}  // namespace bisturi::cli
