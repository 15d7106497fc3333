#pragma once
// Sampled volumes (CT, MR, label maps) and the one world frame of the project.
//
// World frame: DICOM patient coordinates, LPS (x to the patient's left, y to posterior, z to
// superior), in millimetres. Readers convert whatever their file says (NIfTI's RAS, NRRD's
// `space`) into it; every mesh the scene layer extracts or writes is in it.
//
// Index space: sample (i, j, k), i fastest in memory. Sample centres map to the world by
//   world = origin + direction * (spacing * (i, j, k))
// where the columns of `direction` are the unit world directions of +i, +j and +k.

#include <array>
#include <cstddef>
#include <cstdint>
#include <string>

#include <glm/glm.hpp>

#include "bisturi/scene/big_vector.h"

namespace bisturi {

struct VolumeGeometry {
  /// Samples along i, j, k (each at least 1 in a valid volume).
  std::array<std::int64_t, 3> dims{0, 0, 0};
  /// Millimetres between neighbouring sample centres along i, j, k (each > 0).
  glm::dvec3 spacing{1.0};
  /// World position (mm) of sample (0, 0, 0).
  glm::dvec3 origin{0.0};
  /// Columns: world unit directions of +i, +j, +k (orthonormal for every reader's output).
  glm::dmat3 direction{1.0};

  [[nodiscard]] std::size_t voxel_count() const {
    return static_cast<std::size_t>(dims[0]) * static_cast<std::size_t>(dims[1]) *
           static_cast<std::size_t>(dims[2]);
  }
  [[nodiscard]] std::size_t linear_index(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return static_cast<std::size_t>(i + dims[0] * (j + dims[1] * k));
  }
  [[nodiscard]] bool contains(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return i >= 0 && j >= 0 && k >= 0 && i < dims[0] && j < dims[1] && k < dims[2];
  }
  /// World position (mm) of a point in (continuous) index coordinates.
  [[nodiscard]] glm::dvec3 index_to_world(const glm::dvec3& ijk) const {
    return origin + direction * (spacing * ijk);
  }
  /// Continuous index coordinates of a world point (direction must be invertible).
  [[nodiscard]] glm::dvec3 world_to_index(const glm::dvec3& world) const {
    return (glm::inverse(direction) * (world - origin)) / spacing;
  }
};

/// A scalar field on a regular grid: geometry plus one value per sample, i fastest.
template <class T>
struct Grid {
  VolumeGeometry geometry;
  BigVector<T> values;

  [[nodiscard]] const T& at(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return values[geometry.linear_index(i, j, k)];
  }
  [[nodiscard]] T& at(std::int64_t i, std::int64_t j, std::int64_t k) {
    return values[geometry.linear_index(i, j, k)];
  }
};

/// An image volume. Values are in the modality's physical unit where the file gives one (CT:
/// Hounsfield units, after the file's rescale slope and intercept), stored as float.
struct Volume : Grid<float> {
  /// "CT", "MR", ... as the file names it; empty when the file does not say.
  std::string modality;
  /// The file or folder it was read from (for messages); empty for generated volumes.
  std::string source;
};

/// A segmentation: 0 is background, objects are 1..label_count.
struct LabelVolume : Grid<std::uint32_t> {
  std::uint32_t label_count = 0;
};

}  // namespace bisturi
