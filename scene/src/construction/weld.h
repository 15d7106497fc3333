#pragma once
// Internal: procedure 3 of the seed, vertex welding through hashing (linear expected time).

#include <cstdint>
#include <span>
#include <vector>
#include "bisturi/scene/big_vector.h"

#include "bisturi/scene/dlfl.h"

namespace bisturi::construction {

struct WeldResult {
  ScratchVector<std::uint32_t> welded_index;  ///< per input vertex: its index among the kept ones
  BigVector<Dlfl::Vec3> positions;  ///< kept vertices, in order of first appearance (sized exactly,
                                    ///< so the DLFL can take them as they are)
};

/// Merges vertices with bit-identical coordinates (-0 and +0 are equal).
WeldResult weld_exact(std::span<const Dlfl::Vec3> positions);

/// Merges each vertex into the first earlier kept vertex within `tolerance` (a grid of cells of
/// that size; only the 27 cells around a point are searched). Throws InputError when the
/// coordinates are too large for the tolerance's grid.
WeldResult weld_within(std::span<const Dlfl::Vec3> positions, double tolerance);

}  // namespace bisturi::construction
