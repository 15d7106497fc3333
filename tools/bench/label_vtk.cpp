#include "label_vtk.h"

#include <chrono>

#include <vtkCellArray.h>
#include <vtkDiscreteFlyingEdges3D.h>
#include <vtkFloatArray.h>
#include <vtkIdList.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSMPTools.h>
#include <vtkWindowedSincPolyDataFilter.h>

namespace bisturi::bench {

VtkLabelSurface vtk_label_surface(const float* values, const std::int64_t dims[3],
                                  const double spacing[3], const double origin[3], float label,
                                  int threads) {
  vtkSMPTools::Initialize(threads);
  vtkNew<vtkFloatArray> scalars;
  const vtkIdType n = static_cast<vtkIdType>(dims[0] * dims[1] * dims[2]);
  scalars->SetArray(const_cast<float*>(values), n, 1);  // zero copy, not freed by VTK
  vtkNew<vtkImageData> image;
  image->SetDimensions(static_cast<int>(dims[0]), static_cast<int>(dims[1]),
                       static_cast<int>(dims[2]));
  image->SetSpacing(spacing[0], spacing[1], spacing[2]);
  image->SetOrigin(origin[0], origin[1], origin[2]);
  image->GetPointData()->SetScalars(scalars);

  const auto start = std::chrono::steady_clock::now();
  vtkNew<vtkDiscreteFlyingEdges3D> surface;
  surface->SetInputData(image);
  surface->SetValue(0, label);
  surface->ComputeGradientsOff();
  surface->ComputeNormalsOff();
  surface->ComputeScalarsOff();
  vtkNew<vtkWindowedSincPolyDataFilter> smoother;
  smoother->SetInputConnection(surface->GetOutputPort());
  smoother->SetNumberOfIterations(20);
  smoother->SetPassBand(0.01);
  smoother->BoundarySmoothingOff();
  smoother->FeatureEdgeSmoothingOff();
  smoother->NonManifoldSmoothingOn();
  smoother->NormalizeCoordinatesOn();
  smoother->Update();
  VtkLabelSurface out;
  out.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();

  vtkPolyData* poly = smoother->GetOutput();
  const vtkIdType points = poly->GetNumberOfPoints();
  out.points.resize(static_cast<std::size_t>(points) * 3);
  for (vtkIdType i = 0; i < points; ++i)
    poly->GetPoint(i, &out.points[static_cast<std::size_t>(i) * 3]);
  vtkCellArray* polys = poly->GetPolys();
  vtkNew<vtkIdList> ids;
  polys->InitTraversal();
  while (polys->GetNextCell(ids)) {
    if (ids->GetNumberOfIds() != 3) continue;
    for (vtkIdType k = 0; k < 3; ++k)
      out.triangles.push_back(static_cast<std::int64_t>(ids->GetId(k)));
  }
  return out;
}

}  // namespace bisturi::bench
