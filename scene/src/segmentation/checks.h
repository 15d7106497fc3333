#pragma once
// Argument checks shared by the segmentation sources.

#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi::segmentation_detail {

template <class T>
void check_grid(const Grid<T>& grid, const char* what) {
  const auto& d = grid.geometry.dims;
  if (d[0] < 1 || d[1] < 1 || d[2] < 1) {
    throw InputError(std::string(what) + ": volume dimensions " + std::to_string(d[0]) + "x" +
                     std::to_string(d[1]) + "x" + std::to_string(d[2]) +
                     " must be at least 1 along every axis");
  }
  if (grid.values.size() != grid.geometry.voxel_count()) {
    throw InputError(std::string(what) + ": the volume has " + std::to_string(grid.values.size()) +
                     " values for " + std::to_string(grid.geometry.voxel_count()) + " samples");
  }
}

}  // namespace bisturi::segmentation_detail
