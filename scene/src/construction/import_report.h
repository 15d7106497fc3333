#pragma once
// Internal: procedure 5 of the seed (fans, non-manifold vertices and edges) and the figures of
// each part, counted on the input's own elements after welding and cleaning.

#include <cstdint>
#include <span>
#include <vector>

#include "bisturi/scene/polygon_import.h"
#include "edge_groups.h"
#include "orient.h"

namespace bisturi::construction {

struct KeptFaces {
  std::span<const std::uint32_t> offsets;  ///< CSR over kept faces
  std::span<const std::uint32_t> from;     ///< per half-edge, input orientation
  std::span<const std::uint32_t> to;
  std::span<const std::uint32_t> face_of;
  std::size_t vertex_count = 0;  ///< after welding
};

/// Fills the topology fields of `report` (vertices, isolated_vertices, edges, faces,
/// nonmanifold_*, duplicate_faces, parts).
void fill_report(const KeptFaces& kept, const EdgeGroups& groups, const Orientation& orientation,
                 ImportReport& report);

}  // namespace bisturi::construction
