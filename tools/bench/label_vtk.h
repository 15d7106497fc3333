#pragma once
// 3D Slicer's label-map-to-surface pipeline for label_surface_bench, in its own C++17
// translation unit (VTK 9.1's headers are not valid C++20); no VTK or bisturi types here.

#include <cstdint>
#include <vector>

namespace bisturi::bench {

struct VtkLabelSurface {
  std::vector<double> points;           ///< x y z per point, world millimetres
  std::vector<std::int64_t> triangles;  ///< three point indices per triangle
  double seconds = 0.0;                 ///< both filters' Update (not the copies out)
};

/// vtkDiscreteFlyingEdges3D (value `label`) followed by vtkWindowedSincPolyDataFilter with the
/// settings of Slicer's vtkBinaryLabelmapToClosedSurfaceConversionRule at its default smoothing
/// factor 0.5: 20 iterations, pass band 10^(-4 * 0.5) = 0.01, boundary and feature-edge
/// smoothing off, non-manifold smoothing on, normalised coordinates. `values` is the label map
/// (i fastest) with axis-aligned geometry; VTK runs on `threads` threads.
VtkLabelSurface vtk_label_surface(const float* values, const std::int64_t dims[3],
                                  const double spacing[3], const double origin[3], float label,
                                  int threads);

}  // namespace bisturi::bench
