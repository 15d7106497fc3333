#pragma once
// vtkFlyingEdges3D and vtkMarchingCubes for extract_bench, in their own translation unit: VTK
// 9.1's vtkSMPTools.h does not compile as C++20, so vtk_runner.cpp is built as C++17 and this
// header uses no VTK or bisturi types.

#include <cstdint>

namespace bisturi::bench {

/// Sets the number of threads of VTK's SMP backend (vtkSMPTools::Initialize).
void vtk_set_threads(int threads);

/// Extracts the iso surface of an n^3 float volume (i fastest, 0.5 mm spacing) with
/// vtkFlyingEdges3D (flying_edges) or vtkMarchingCubes, without normals, gradients or scalars.
/// Returns the triangle count.
std::int64_t vtk_extract(const float* values, std::int64_t n, float iso, bool flying_edges);

}  // namespace bisturi::bench
