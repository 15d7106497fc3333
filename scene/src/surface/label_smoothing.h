#pragma once
// Steps 3 to 5 of label surfaces (label_surface.h): the windowed-sinc low-pass with twicing, the
// band constraint, the tangential relaxation and the fit to smooth normals, on the vertex
// positions of a marching-cubes surface (its topology kept).

#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/label_surface.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi {

/// Each vertex's neighbours (CSR): the far ends of its edges.
struct Neighbours {
  std::vector<std::uint32_t> offsets;
  std::vector<std::uint32_t> adjacency;
  /// Per entry of adjacency, the corner before v in the same face: (v, next, before) spans that
  /// face, so the vertex's normal is their cross products' sum.
  std::vector<std::uint32_t> before;
};

Neighbours neighbours_of(const PolygonMesh& mesh);
Neighbours neighbours_of(const Dlfl& mesh);

/// Steps 3 to 5 on `pos` (the marching-cubes positions after steps 1 and 2), every vertex kept in
/// the band of cells where `band` (the label's 0/1 indicator) changes.
void smooth_in_band(std::span<Dlfl::Vec3> pos, const Neighbours& nb, const Grid<float>& band,
                    const LabelSurfaceOptions& o, LabelSurfaceStats& stats);

}  // namespace bisturi
