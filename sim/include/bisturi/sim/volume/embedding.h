#pragma once
// Surface points that follow a hexahedral lattice: each sits in one kept cell and moves with
// its 8 nodes by trilinear interpolation (SOFA's BarycentricMapping on a SparseGridTopology does
// the same). A force on the point goes to the nodes with the same weights, so the mapping
// conserves work.

#include <array>
#include <cstdint>
#include <optional>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/volume/hex_lattice.h"

namespace bisturi::sim {

struct EmbeddedPoint {
  std::uint32_t cell = 0;
  std::array<double, 8> weights{};  ///< by corner, summing to 1
};

/// The point's cell and weights at rest, or none when it lies in no kept cell.
std::optional<EmbeddedPoint> embed_point(const HexLattice& lattice, const glm::dvec3& point);

/// The point's cell and weights at rest; a point in no kept cell (a drawn surface finer than the
/// one the lattice was built around pokes out of it by a fraction of a cell) takes the nearest
/// kept cell, its weights extrapolated (they still sum to 1: the cell's motion, continued). None
/// only for a lattice without cells.
std::optional<EmbeddedPoint> embed_point_nearest(const HexLattice& lattice,
                                                 const glm::dvec3& point);

/// The point's weights in kept cell `cell`, extrapolated past its faces when it lies outside.
EmbeddedPoint embed_point_in(const HexLattice& lattice, std::uint32_t cell,
                             const glm::dvec3& point);

/// Each point's cell and weights at rest. Throws std::invalid_argument naming the first point
/// that lies in no kept cell.
std::vector<EmbeddedPoint> embed_points(const HexLattice& lattice,
                                        std::span<const glm::dvec3> points);

/// Where an embedded point is with the lattice's nodes at `nodes`.
glm::dvec3 embedded_position(const HexLattice& lattice, std::span<const glm::dvec3> nodes,
                             const EmbeddedPoint& point);

}  // namespace bisturi::sim
