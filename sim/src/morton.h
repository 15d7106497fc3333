#pragma once
// Morton (Z-order) codes of points on a 1024-cell grid per axis: sorting by them keeps nearby
// points together (the BVH's surface patches, the multirate far field's blocks of aggregates).

#include <algorithm>
#include <cstdint>

#include <glm/vec3.hpp>

namespace bisturi::sim {

/// Spreads the low 10 bits of v to every third bit.
inline std::uint32_t spread_bits(std::uint32_t v) {
  v &= 0x3ffu;
  v = (v | (v << 16)) & 0x030000ffu;
  v = (v | (v << 8)) & 0x0300f00fu;
  v = (v | (v << 4)) & 0x030c30c3u;
  v = (v | (v << 2)) & 0x09249249u;
  return v;
}

/// u's cell on a 1024-cell axis (0 for a NaN: a position the guard has not rolled back yet must
/// not make the cast undefined).
inline std::uint32_t morton_cell(double u) {
  return u > 0.0 ? static_cast<std::uint32_t>(std::min(u, 1023.0)) : 0u;
}

/// The 30-bit code of a point given in cells (each axis in [0, 1024)), x in the lowest bit.
inline std::uint32_t morton_code(const glm::dvec3& cells) {
  return spread_bits(morton_cell(cells.x)) | (spread_bits(morton_cell(cells.y)) << 1) |
         (spread_bits(morton_cell(cells.z)) << 2);
}

}  // namespace bisturi::sim
