#pragma once
// Smooth surfaces of label maps. Marching cubes on a label's 0/1 indicator puts every vertex at
// the midpoint of a grid edge from an inside to an outside sample, so the surface follows the
// voxels: terraces one slice high, tall ones where slices are thick (a CT label map at
// 0.6 x 0.6 x 1.3 mm, or 1 x 1 x 3). Here, on the same crossed edges (the same vertices and
// triangles, so the same closed, oriented 2-manifold of the same genus):
// 1. shape-based interpolation (Raya and Udupa, 1990): each slice's samples hold their signed
//    in-slice distance (mm) to the label's outline, and each crossed edge is cut where that
//    interpolates to zero, so between slices the outline moves smoothly. Runs of identical
//    slices (a map resampled from thicker slices by repetition) are interpolated between their
//    middles;
// 2. caps: where the slice beyond a label's last one holds none of it (its ends, or a gap
//    between two objects), the vertices on the edges into it go onto a cap fitted to how the
//    region narrows over its last slices instead (scene/src/surface/label_caps.h);
// 3. the windowed-sinc low-pass of Taubin, Zhang and Golub ("Optimal surface smoothing as
//    filter design", 1996; the filter 3D Slicer applies through VTK), its cut set so that the
//    gain at the pass band is 1 (the shape itself does not shrink);
// 4. the band constraint: a vertex the filter carried out of the band of cells the outline runs
//    through (cells with inside and outside corners) goes back along the way it came to where
//    the band ends, as constrained surface nets keep each vertex in its cell. Thin parts cannot
//    melt away;
// 5. the triangles even out within the surface (tangential relaxation), then each vertex moves
//    along its faces' smooth normals until they lie across them.
// Only positions move (outside repeated slices, whose interpolated sign may differ from the
// indicator's). The slices are taken across the axis whose samples lie furthest apart (a
// sagittal or coronal series as well as an axial one); along k where spacings tie. Figures against
// the plain extraction and against VTK's 3D Slicer pipeline (vtkDiscreteFlyingEdges3D +
// vtkWindowedSincPolyDataFilter): tools/bench/label_surface_bench.cpp, table in
// docs/scene/label-surfaces.md.

#include <array>
#include <cstddef>
#include <functional>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

struct LabelSurfaceOptions {
  /// Order of the windowed-sinc filter (neighbour sweeps per round); 0: step 1 only.
  std::size_t iterations = 20;
  /// Pass band of the filter (frequencies of the umbrella Laplacian, 0..2): lower is smoother.
  double pass_band = 0.01;
  /// Filter passes, each followed by the band constraint. Passes after the first filter what is
  /// left between the result and the marching-cubes positions and add it back (Tukey's
  /// twicing): less shrinkage of small curved parts, more of the staircase left. Two by default:
  /// with the caps over the last slices, twicing brings every distance figure of the label
  /// surface bench under VTK's (docs/scene/label-surfaces.md).
  std::size_t rounds = 2;
  /// The share of each later round's filtered residual that is added back (1: Tukey's
  /// twicing), in [0, 2], set per vertex by how sharply the surface bends there against its
  /// sampling after the first round: the largest turn of its normal to a neighbour per
  /// millimetre, times its mean edge length, averaged over its neighbourhood. Where that bend
  /// is twicing_bend_flat or less (a wide curve over many samples) the residual is mostly the
  /// staircase, and adding it back brings back part of the terraces: twicing_share_flat. From
  /// twicing_bend_sharp on (a thin tube or a rounded end over a few samples) it is mostly shape
  /// the filter took away: twicing_share. Linear between. Equal shares: one share everywhere.
  double twicing_share = 1.0;
  double twicing_share_flat = 0.3;
  double twicing_bend_flat = 0.1;
  double twicing_bend_sharp = 0.3;
  /// Rounds after those that add back only where the surface bends sharply (the share
  /// twicing_share from twicing_bend_sharp on, none up to twicing_bend_flat, linear between), on
  /// maps whose slices lie further apart than their samples within a slice by a fifth or more.
  /// There a solid only a few slices high (a flat organ's rim between thick slices) is drawn in
  /// by the filter more than the twicing's shares bring back, while its flat parts' residual is
  /// the terraces. One by default: against VTK over the label surface bench's spacings it
  /// brings the figures lost from 12 to 8 of 1020 (with eight sweeps of the fit), and the vessel's
  /// distance figures over its tilts and radii from 8 to 3 of 144 (docs/scene/label-surfaces.md).
  std::size_t sharp_rounds = 1;
  /// Sweeps that move each vertex along the smooth normals of its faces until the faces lie
  /// across them (the vertex update of Sun, Rosin, Martin and Langbein 2007), each followed by
  /// the band constraint: thin triangles spanning a slice no longer tilt with their corners'
  /// small errors. Eight by default: against VTK over the label surface bench's spacings, with
  /// a vessel lying across the slices, they lose half as many figures as three did, for a fifth
  /// more time (docs/scene/label-surfaces.md).
  std::size_t normal_fit_sweeps = 8;
  /// The same where the slices lie further apart than the samples within them by a fifth or
  /// more (as for sharp_rounds), whose thin triangles across each slice are longer. Sixteen by
  /// default: with the sharp round, over the bench's spacings they lose 4 figures to VTK of
  /// 1020 against 8 with eight sweeps, 7 with twelve and 6 with twenty-four.
  std::size_t normal_fit_sweeps_thick = 16;
  /// Sweeps before those that move each vertex towards the area-weighted centre of its faces
  /// within its tangent plane, each followed by the band constraint: the thin triangles left
  /// where a thin part ends in a slice even out, and their normals with them. Ten by default:
  /// against VTK over the label surface bench's spacings they lose a third fewer figures, all
  /// of the vessel's worst normals among them (docs/scene/label-surfaces.md).
  std::size_t tangential_sweeps = 10;
  /// Called with (done, total) slabs of cells, then with the DLFL build (extract_label_surface).
  std::function<void(std::size_t, std::size_t)> progress;
  std::function<void(std::size_t, std::size_t)> build_progress;
  /// Called with (rounds done, rounds), the sharp rounds counted in.
  std::function<void(std::size_t, std::size_t)> smooth_progress;
};

struct LabelSurfaceStats {
  ExtractionStats extraction;
  std::size_t label_voxels = 0;
  /// Vertices the band constraint pulled back in the last round.
  std::size_t clamped_last = 0;
  double indicator_seconds = 0.0;
  double smooth_seconds = 0.0;
};

/// A coarser label map for a coarser surface (a tissue model of a few hundred vertices from a
/// CT label map, without decimating a surface of hundreds of thousands): blocks of
/// factors[0] x factors[1] x factors[2] samples become one sample, `label` when at least half of
/// the block's samples are, 0 otherwise, at the block's centre. Blocks at the far ends hold what
/// samples are left; one sample of background (0) goes around the result, so the surface is
/// closed even where the label reaches the map's edge. Throws InputError for a factor below 1 or a
/// `label` of 0.
Grid<float> downsample_label(const Grid<float>& labels, float label,
                             const std::array<int, 3>& factors);

/// Samples whose value equals `label`.
std::size_t label_voxel_count(const Grid<float>& labels, float label);

/// The smooth surface of the samples whose value equals `label`, as indexed triangles (world
/// millimetres, outward normals). Throws InputError as extract_isosurface_mesh does, and for
/// one iteration or a pass band outside (0, 2). A label absent from the volume gives an empty
/// mesh.
PolygonMesh extract_label_surface_mesh(const Grid<float>& labels, float label,
                                       const LabelSurfaceOptions& options = {},
                                       LabelSurfaceStats* stats = nullptr);

/// The same surface as a Dlfl (extract_isosurface's structure; vertex v is vertex v of the mesh).
Dlfl extract_label_surface(const Grid<float>& labels, float label,
                           const LabelSurfaceOptions& options = {},
                           LabelSurfaceStats* stats = nullptr);

}  // namespace bisturi
