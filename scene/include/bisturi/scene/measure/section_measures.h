#pragma once
// Measures of a cross-section loop (plane_cut.h) and the orthogonal section of a vessel.
//
// A closed loop is measured as the smooth curve its points sample, not as the polygon:
//  1. points: CutLoop::surface_points when present (cut points moved from the mesh's chords onto
//     the smooth surface, see plane_cut.h), else the polygon's points;
//  2. the curve: a truncated Fourier series z(u) = sum_{|k|<=K} c_k e^{iku} of the points in
//     plane coordinates, fitted by weighted least squares (u: 2 pi times the fraction of the
//     polygon's length, weights: each point's share of that length). K keeps only wavelengths
//     longer than `cutoff_spacings` times the mesh's edge length near the loop, so the zig-zag
//     a cut through a triangle mesh adds at the scale of its edges (which makes a polygon's
//     perimeter 0.1-1% long) is filtered out while the vessel's shape (any smooth, even strongly
//     elliptical section) is kept. The fit passes through the points in the least-squares sense,
//     so the curve is not pulled inside the way chords are;
//  3. measures of that curve: perimeter = integral of |z'(u)| (trapezoid rule on M >= 16 K
//     samples, spectrally accurate for a periodic curve), area = pi sum k |c_k|^2 (exact for the
//     series), centroid, mean distance and calipers from the M samples.
// MeasureOptions::smooth = false measures the polygon itself (still with surface points when the
// cut made them). An open loop (it ends at the mesh's boundary) is measured as a polygon: its
// perimeter is its length, its area and centroid those of the polygon closed by the chord
// between its ends.

#include <cstddef>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/measure/plane_cut.h"

namespace bisturi {

struct MeasureOptions {
  /// Measure closed loops as the smooth curve they sample (see above); false: as polygons.
  bool smooth = true;
  /// Shortest wavelength kept, in mesh edge lengths (the median length of the crossed edges).
  double cutoff_spacings = 4.0;
  /// Drop the harmonics that do not stand out of the noise floor (the median power of the upper
  /// half of the band): keep k up to the last harmonic whose power exceeds 4 times the floor.
  bool adaptive_cutoff = true;
  /// Use CutLoop::surface_points when the cut made them.
  bool use_surface_points = true;
};

struct LoopMeasures {
  bool closed = false;
  glm::dvec3 centroid{0.0};          ///< area centroid (world mm, in the plane)
  double area = 0.0;                 ///< mm^2
  double perimeter = 0.0;            ///< mm (an open loop: its length)
  double mean_diameter = 0.0;        ///< twice the mean distance from the centroid, by arc length
  double equivalent_diameter = 0.0;  ///< 2 sqrt(area / pi)
  double min_caliper = 0.0;          ///< smallest width (Feret), rotating calipers on the hull
  double max_caliper = 0.0;          ///< largest width (Feret)
  glm::dvec3 normal{0.0};            ///< the plane's unit normal
  std::size_t faces_touched = 0;
  std::size_t points = 0;     ///< points of the loop
  std::size_t harmonics = 0;  ///< K of the smooth curve (0: measured as a polygon)
  double polygon_area = 0.0;  ///< the raw polygon (CutLoop::points), for comparison
  double polygon_perimeter = 0.0;
};

/// Measures one loop of `cut` (plane normal from the cut).
LoopMeasures measure_loop(const CutLoop& loop, const Plane& plane,
                          const MeasureOptions& options = {});

/// Every loop of a cut, in its order.
std::vector<LoopMeasures> measure_cut(const PlaneCut& cut, const MeasureOptions& options = {});

struct OrthogonalOptions {
  /// Starting half-width of the search simplex in tilt (tangent of the angle).
  double initial_step = 0.15;
  /// Stop when the simplex is smaller than this (tangent of the angle).
  double tolerance = 1e-6;
  std::size_t max_evaluations = 400;
  CutOptions cut;
  MeasureOptions measure;
};

struct OrthogonalSection {
  bool found = false;     ///< a closed loop around the point exists in the final plane
  Plane plane;            ///< through the given point, unit normal (sign of the given direction)
  CutLoop loop;           ///< the loop around the point
  LoopMeasures measures;  ///< of that loop
  std::size_t evaluations = 0;  ///< cuts made by the search
  double tilt_degrees = 0.0;    ///< angle between the given and the found normal
};

/// The plane through `point` whose section of the loop around the point has the smallest area
/// (the orthogonal section of a vessel, bent or not), searched by Nelder-Mead over the two tilts
/// of the normal away from `direction`. The loop around the point is the closed loop whose
/// polygon winds around it (the smallest if several); without one, the closest closed loop.
/// The objective is the area of the surface-point polygon (cheap and smooth in the tilts); the
/// final plane is measured with `options.measure`. Throws InputError for a zero direction.
OrthogonalSection find_orthogonal_section(const CutIndex& index, const glm::dvec3& point,
                                          const glm::dvec3& direction,
                                          const OrthogonalOptions& options = {});

}  // namespace bisturi
