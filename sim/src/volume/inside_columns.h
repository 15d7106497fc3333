#pragma once
// Which points of a rectilinear sample grid lie inside a closed triangle surface, by ray parity
// along z: one ray per (x, y) column, its crossings sorted, so a column of samples costs one
// sort. Triangles are bucketed by their xy bounds, so a column meets only those above it. The
// rays are nudged off the grid by a tiny irrational offset, so none runs along an edge.

#include <array>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

namespace bisturi::sim {

/// inside[(k * ys.size() + j) * xs.size() + i] for the point (xs[i], ys[j], zs[k]); zs sorted.
std::vector<std::uint8_t> inside_columns(std::span<const glm::dvec3> vertices,
                                         std::span<const std::array<std::uint32_t, 3>> triangles,
                                         std::span<const double> xs, std::span<const double> ys,
                                         std::span<const double> zs);

}  // namespace bisturi::sim
