#pragma once
// vtkCutter + vtkStripper for measure_bench, in their own C++17 translation unit (VTK 9.1's
// vtkSMPTools.h is not valid C++20); this header uses no VTK or bisturi types.

#include <cstdint>

namespace bisturi::bench {

/// A vtkPolyData of triangles built from the caller's arrays (copied once).
class VtkCutMesh {
 public:
  VtkCutMesh(const double* xyz, std::int64_t points, const std::uint32_t* triangles,
             std::int64_t triangle_count);
  ~VtkCutMesh();
  VtkCutMesh(const VtkCutMesh&) = delete;
  VtkCutMesh& operator=(const VtkCutMesh&) = delete;

  /// vtkCutter with a vtkPlane, then vtkStripper joining the segments into polylines. Returns
  /// the number of polylines (loops); *points receives the number of output points.
  std::int64_t cut(const double point[3], const double normal[3], std::int64_t* points);

 private:
  struct Impl;
  Impl* impl_;
};

}  // namespace bisturi::bench
