#pragma once
// Sections of a vessel orthogonal to its centreline, through the walk-based plane measurement
// (measure/plane_cut.h, measure/section_measures.h) on the vessel's surface.
//
// recentre_on_surface moves every centreline point (a smoothed voxel path, centreline.h) to the
// area centroid of the surface's cross-section in the plane through the point normal to the
// local tangent: the loop that winds around the point. That is the centre of the lumen to the
// accuracy of the surface, well inside a voxel. Points whose plane has no loop around them
// (at a bifurcation's crotch, where the plane cuts two branches at once) keep their place.
//
// measure_sections cuts the surface every step_mm of distance along the centreline (at the same
// distances on every branch, counted from the start, so daughters line up), with the plane
// through the centreline point that gives the smallest section (find_orthogonal_section, started
// from the tangent). Sections closer to a tip than end_margin_radii radii (the
// centreline runs a radius into the end's cap, and a plane within a radius of the cap tilts into
// it), or to a bifurcation than junction_margin_radii radii (where the section is not the
// vessel's), are left out.

#include <cstddef>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/measure/plane_cut.h"
#include "bisturi/scene/measure/section_measures.h"
#include "bisturi/scene/vessel/centreline.h"

namespace bisturi {

struct RecentreStats {
  std::size_t moved = 0;  ///< points moved onto a section's centroid
  std::size_t kept = 0;   ///< points with no loop around them
  double max_move_mm = 0.0;
};

/// Moves the points of every branch onto the section centroids (ends stay put) and recomputes
/// the distances along the centreline.
RecentreStats recentre_on_surface(const CutIndex& index, Centreline& centreline);

struct SectionOptions {
  double step_mm = 2.0;
  double end_margin_radii = 2.5;
  double junction_margin_radii = 2.0;
  /// Search the smallest section through each point (else: the plane normal to the tangent).
  bool orthogonal_search = true;
  MeasureOptions measure;
};

struct VesselSection {
  int branch = 0;
  double distance_mm = 0.0;  ///< along the centreline from its start
  glm::dvec3 centre{0.0};    ///< the section's area centroid (world LPS mm)
  glm::dvec3 normal{0.0};    ///< unit, pointing down the centreline
  LoopMeasures measures;
  double tilt_degrees = 0.0;  ///< between the tangent and the section's normal
  std::size_t cuts = 0;       ///< plane cuts the search made
};

struct SectionsResult {
  std::vector<VesselSection> sections;  ///< by branch, then distance
  std::size_t skipped_no_loop = 0;      ///< sample points with no closed loop around them
};

/// Throws InputError for a step that is not positive and finite.
SectionsResult measure_sections(const CutIndex& index, const Centreline& centreline,
                                const SectionOptions& options = {});

/// The point and unit tangent at `distance_mm` along `branch` (linear between its points;
/// the tangent over about a radius either side). Distances outside the branch are clamped.
struct CentrelineSample {
  glm::dvec3 point{0.0};
  glm::dvec3 tangent{0.0, 0.0, 1.0};
  double radius_mm = 0.0;
};
CentrelineSample sample_branch(const CentrelineBranch& branch, double distance_mm);

}  // namespace bisturi
