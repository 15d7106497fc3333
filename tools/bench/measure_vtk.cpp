#include "measure_vtk.h"

#include <vtkCellArray.h>
#include <vtkCutter.h>
#include <vtkNew.h>
#include <vtkPlane.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkSmartPointer.h>
#include <vtkStripper.h>

namespace bisturi::bench {

struct VtkCutMesh::Impl {
  vtkSmartPointer<vtkPolyData> poly = vtkSmartPointer<vtkPolyData>::New();
};

VtkCutMesh::VtkCutMesh(const double* xyz, std::int64_t points, const std::uint32_t* triangles,
                       std::int64_t triangle_count)
    : impl_(new Impl) {
  vtkNew<vtkPoints> pts;
  pts->SetDataTypeToDouble();
  pts->SetNumberOfPoints(static_cast<vtkIdType>(points));
  for (std::int64_t i = 0; i < points; ++i)
    pts->SetPoint(static_cast<vtkIdType>(i), xyz + 3 * i);
  vtkNew<vtkCellArray> cells;
  cells->AllocateExact(static_cast<vtkIdType>(triangle_count),
                       static_cast<vtkIdType>(3 * triangle_count));
  for (std::int64_t t = 0; t < triangle_count; ++t) {
    const vtkIdType ids[3] = {static_cast<vtkIdType>(triangles[3 * t]),
                              static_cast<vtkIdType>(triangles[3 * t + 1]),
                              static_cast<vtkIdType>(triangles[3 * t + 2])};
    cells->InsertNextCell(3, ids);
  }
  impl_->poly->SetPoints(pts);
  impl_->poly->SetPolys(cells);
  impl_->poly->BuildCells();
}

VtkCutMesh::~VtkCutMesh() {
  delete impl_;
}

std::int64_t VtkCutMesh::cut(const double point[3], const double normal[3], std::int64_t* points) {
  vtkNew<vtkPlane> plane;
  plane->SetOrigin(point[0], point[1], point[2]);
  plane->SetNormal(normal[0], normal[1], normal[2]);
  vtkNew<vtkCutter> cutter;
  cutter->SetInputData(impl_->poly);
  cutter->SetCutFunction(plane);
  cutter->GenerateCutScalarsOff();
  vtkNew<vtkStripper> stripper;
  stripper->SetInputConnection(cutter->GetOutputPort());
  stripper->JoinContiguousSegmentsOn();
  stripper->Update();
  vtkPolyData* out = stripper->GetOutput();
  if (points != nullptr) *points = out->GetNumberOfPoints();
  return out->GetNumberOfLines();
}

}  // namespace bisturi::bench
