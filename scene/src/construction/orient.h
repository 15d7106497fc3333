#pragma once
// Internal: procedure 4 of the seed. A stack walk across edges in exactly two faces orients each
// face like the face it was reached from and collects the parts. Where the walk meets a face it
// already oriented the other way, the part is non-orientable and that edge becomes a seam (both
// sides are treated as boundary), so every part can be stored as an oriented surface.

#include <cstdint>
#include <span>
#include <vector>
#include "bisturi/scene/big_vector.h"

#include "edge_groups.h"

namespace bisturi::construction {

struct Orientation {
  ScratchVector<char> flip;  ///< per face: reverse it
  ScratchVector<std::uint32_t> part_of_face;
  ScratchVector<char> seam;             ///< per edge group
  ScratchVector<char> part_orientable;  ///< per part
  std::size_t part_count = 0;
  std::size_t seam_count = 0;
};

Orientation orient_faces(std::span<const std::uint32_t> offsets,
                         std::span<const std::uint32_t> from,
                         std::span<const std::uint32_t> face_of, const EdgeGroups& groups);

}  // namespace bisturi::construction
