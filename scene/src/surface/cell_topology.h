#pragma once
// Marching cubes, direct DLFL build (marching_cubes.cpp): for each side of each triangle of a
// cube-case entry, where its twin is. A side whose reverse is in the same entry pairs inside the
// cell; every other side is a segment on one cube face, shared with the cell across that face.

#include <array>
#include <cstdint>
#include <vector>

namespace bisturi::surface {

/// The twins of the cube cases' triangle sides (the cell across a face decides it alike).
struct CellTopology {
  static constexpr std::uint8_t kInterior = 8;
  /// Per side (3 per triangle, parallel to CubeCases::triangle_codes), for the emitted winding
  /// [flip]: the cube face (0..5) it lies on, or kInterior + the entry-local side of its twin.
  std::array<std::vector<std::uint8_t>, 2> side_class;
  /// Per entry: the number of sides on cube face f in bits 2f..2f+1.
  std::vector<std::uint16_t> face_sides;
};

/// The table for cube_cases(), built on first use.
const CellTopology& cell_topology();

}  // namespace bisturi::surface
