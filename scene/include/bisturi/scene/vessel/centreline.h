#pragma once
// The centreline of a segmented vessel tree: a pruned skeleton of its distance field, as a tree
// of branches that meet at bifurcations.
//
// Method (TEASAR: Sato, Bitter, Kaufman et al., "TEASAR: tree-structure extraction algorithm for
// accurate and robust skeletons", 2000). On the mask's voxels (26-neighbours, steps in world mm):
//  1. the distance field D (distance_field.h) and its maximum M;
//  2. a root: the voxel farthest (geodesically) from the deepest voxel, i.e. an end of the tree;
//  3. two shortest-path fields from the root: plain lengths (the distance from the root) and
//     lengths weighted by 1 + 5000 (1 - D / M)^4 (Sato: ^16, which lets paths cut bends by half
//     a radius), whose shortest paths keep to the ridge of D
//     (the middle of the vessel);
//  4. repeatedly: the voxel farthest from the root that no branch covers yet is a tip; its
//     weighted shortest path back to the skeleton found so far is a new branch, and every voxel
//     within ball_scale D + ball_voxels voxels of that path is covered. A path shorter than
//     min_branch_mm (by default prune_radii times D where it joins) is a spur from a bump or a
//     corner and is dropped (its voxels stay covered).
// The skeleton is a subtree of the weighted shortest-path tree; its voxels with two or more
// children are the bifurcations, and the runs between root, bifurcations and tips are the
// branches. The start (root) is then chosen among the ends: the one nearest `start_mm` when
// given, else the end of the widest terminal branch (a trunk before its daughters), and the
// skeleton is traced again from it, so distances run from the start.
//
// Finally each branch's voxel path (a staircase) is smoothed by a Gaussian over arc length whose
// window shrinks near the branch's ends (ends stay put, so branches still meet). The points lie
// within about half a voxel of the true axis; recentre_on_surface (vessel_sections.h) moves them
// onto the centroids of the surface's cross-sections.

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/volume/volume.h"

namespace bisturi {

struct CentrelineOptions {
  /// Branches shorter than this are pruned; 0: prune_radii times the radius where they join.
  double min_branch_mm = 0.0;
  double prune_radii = 3.0;
  /// A branch covers the voxels within ball_scale * D + ball_voxels * (largest spacing) of it.
  double ball_scale = 2.0;
  double ball_voxels = 2.0;
  /// Gaussian smoothing of the voxel path (sigma, mm); 0: twice the largest spacing.
  double smoothing_mm = 0.0;
  /// The end nearest this world point (LPS mm) is the start; none: the widest end.
  std::optional<glm::dvec3> start_mm;
};

struct CentrelineBranch {
  int id = 0;
  int parent = -1;  ///< the branch this one leaves from (-1: the root branch)
  /// World points (LPS mm) from the branch's first point (the start or a bifurcation) to its
  /// last (a tip or a bifurcation).
  std::vector<glm::dvec3> points;
  /// Distance-field radius (mm) at each point's voxel.
  std::vector<double> radius_mm;
  /// Distance along the centreline from the start of the tree (mm), at each point.
  std::vector<double> distance_mm;
  bool ends_at_tip = true;  ///< false: ends at a bifurcation
  [[nodiscard]] double length_mm() const {
    return distance_mm.empty() ? 0.0 : distance_mm.back() - distance_mm.front();
  }
};

struct Centreline {
  std::vector<CentrelineBranch> branches;  ///< the root branch first; parents before children
  std::vector<glm::dvec3> bifurcations;    ///< world points where branches meet
  std::size_t mask_voxels = 0;             ///< voxels of the object the skeleton covers
  std::size_t pruned_branches = 0;
  double max_radius_mm = 0.0;
};

/// The centreline of the object in `mask` (nonzero voxels) that holds the deepest voxel.
/// Throws InputError for an empty mask or values that do not match the dims.
[[nodiscard]] Centreline extract_centreline(const Grid<std::uint8_t>& mask,
                                            const CentrelineOptions& options = {});

}  // namespace bisturi
