#include "vtk_runner.h"

#include <vtkFloatArray.h>
#include <vtkFlyingEdges3D.h>
#include <vtkImageData.h>
#include <vtkMarchingCubes.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPolyData.h>
#include <vtkSMPTools.h>

namespace bisturi::bench {

void vtk_set_threads(int threads) {
  vtkSMPTools::Initialize(threads);
}

namespace {

template <class Filter>
std::int64_t run(vtkImageData* image, float iso) {
  vtkNew<Filter> filter;
  filter->SetInputData(image);
  filter->SetValue(0, iso);
  filter->ComputeNormalsOff();
  filter->ComputeGradientsOff();
  filter->ComputeScalarsOff();
  filter->Update();
  return filter->GetOutput()->GetNumberOfPolys();
}

}  // namespace

std::int64_t vtk_extract(const float* values, std::int64_t n, float iso, bool flying_edges) {
  vtkNew<vtkFloatArray> scalars;
  // Zero copy: VTK reads the caller's array and does not free it (save = 1).
  scalars->SetArray(const_cast<float*>(values), static_cast<vtkIdType>(n * n * n), 1);
  scalars->SetName("values");
  vtkNew<vtkImageData> image;
  image->SetDimensions(static_cast<int>(n), static_cast<int>(n), static_cast<int>(n));
  image->SetSpacing(0.5, 0.5, 0.5);
  image->GetPointData()->SetScalars(scalars);
  return flying_edges ? run<vtkFlyingEdges3D>(image, iso) : run<vtkMarchingCubes>(image, iso);
}

}  // namespace bisturi::bench
