#pragma once
// Vessel phantoms with a known axis and radius profile, sampled like a contrast CT: the lumen
// at lumen_hu, the background at background_hu, a blurred edge (value = background + (lumen -
// background) (1 + tanh(d / edge)) / 2, d: the signed distance to the true wall, mm, positive
// inside), so the wall is where the value crosses the mid value. Optional Gaussian noise.
//
// Shapes (axis lengths in mm; ends are rounded caps): straight (constant radius), curved (an arc
// of bend_radius_mm), tapering (the radius changes linearly from radius_mm to end_radius_mm) and
// bifurcating (a trunk of radius_mm that splits at half the length into two daughters of
// end_radius_mm, each spread_degrees off the trunk's direction). The axis is tilted off the grid
// (tilt_degrees about two axes) and placed at a world offset, so nothing lines up with voxels.
// The truth is the axis as straight pieces (arcs as chords of 1 degree, 0.001 mm off the arc at
// 30 mm) with the radius at each end.

#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

enum class VesselShape { Straight, Curved, Tapering, Bifurcating };

struct VesselPhantomOptions {
  VesselShape shape = VesselShape::Straight;
  double radius_mm = 4.0;
  /// Tapering: radius at the far end; bifurcating: the daughters' radius (0: 0.7 radius_mm).
  double end_radius_mm = 0.0;
  double length_mm = 50.0;
  double bend_radius_mm = 30.0;
  double spread_degrees = 35.0;
  double tilt_degrees = 11.0;
  glm::dvec3 spacing{0.8};
  /// World position (LPS mm) of the volume's first sample.
  glm::dvec3 origin{-31.3, 12.7, 84.1};
  double lumen_hu = 300.0;
  double background_hu = 0.0;
  /// Edge blur (mm); 0: 1.5 times the largest spacing.
  double edge_mm = 0.0;
  double noise_hu = 0.0;
  unsigned seed = 1;
  /// The volume's extent (mm) at least this along each axis, the vessel in its middle (a scan's
  /// field of view around it, e.g. 360 x 360 x 180 for a CT of 512 x 512 x 256 at 0.7 mm);
  /// 0: the vessel's bounding box and a margin.
  glm::dvec3 field_of_view_mm{0.0};
};

/// A straight piece of the true axis, world mm, with the lumen's radius at each end.
struct AxisPiece {
  glm::dvec3 a{0.0}, b{0.0};
  double radius_a = 0.0, radius_b = 0.0;
};

struct AxisNearest {
  double distance_mm = 0.0;  ///< from the query point to the axis
  double radius_mm = 0.0;    ///< the true radius at the nearest axis point
  glm::dvec3 point{0.0};
  std::size_t piece = 0;
};

struct VesselPhantom {
  Volume volume;
  std::vector<AxisPiece> axis;
  /// The piece index where each branch starts: the trunk (or the only vessel) at 0, then the
  /// daughters.
  std::vector<std::size_t> branch_first_piece;
  /// The threshold that separates lumen from background: the mid value.
  double mid_hu = 0.0;
  [[nodiscard]] AxisNearest nearest(const glm::dvec3& p) const;
};

/// Throws InputError for sizes that are not positive or a taper to a non-positive radius.
[[nodiscard]] VesselPhantom make_vessel_phantom(const VesselPhantomOptions& options);

[[nodiscard]] std::string_view to_string(VesselShape shape);
/// Throws InputError naming the valid shapes.
[[nodiscard]] VesselShape vessel_shape_from_string(std::string_view name);

}  // namespace bisturi
