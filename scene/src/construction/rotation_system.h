#pragma once
// Internal: the target rotation system that both mesh builders hand to the DLFL operators.
//
// Half-edges of the polygons come first (index = position in PolygonMesh::indices), hole
// half-edges after. close_boundaries() gives every boundary half-edge a hole twin, links the
// holes into loops and groups the half-edges leaving each vertex into fans (one fan = one DLFL
// rotation). insert_rotation_system() then builds it with create_vertex / add_rotation /
// insert_edge: vertices first, a spanning forest of edges (each a merge with a point sphere),
// then every other edge next to its predecessor in the target rotation of both ends. When every
// rotation matches the target, every face does too.

#include <cstdint>
#include <functional>
#include <span>
#include <vector>
#include "bisturi/scene/big_vector.h"

#include "bisturi/scene/dlfl.h"

namespace bisturi::construction {

inline constexpr std::uint32_t kNone = kInvalidIndex;

struct RotationSystem {
  ScratchVector<std::uint32_t> from, to, next, twin;  // per half-edge; twin kNone: boundary
  ScratchVector<std::uint32_t> fan;                   // per half-edge: the fan it leaves from
  ScratchVector<std::uint32_t> fan_vertex;            // per fan
  ScratchVector<std::uint32_t> hole_loops;            // one hole half-edge per boundary loop
  std::uint32_t face_half_edges = 0;
};

/// Fills from/to/next for the polygons (face half-edges only; twins all kNone).
void read_polygon_half_edges(std::span<const std::uint32_t> indices,
                             std::span<const std::uint32_t> offsets, RotationSystem& rs);

/// Adds hole half-edges for every boundary half-edge, their loops, and the fans of every
/// vertex. Precondition: twins are symmetric and join opposite half-edges.
void close_boundaries(RotationSystem& rs);

struct InsertOptions {
  /// Per input vertex: an existing vertex whose new rotation(s) take its fans, or invalid.
  std::span<const VertexId> join_vertices;
  std::function<void(std::size_t, std::size_t)> progress;
};

/// Builds the rotation system into `dlfl`; returns the vertex handle of every input vertex.
/// Vertices without fans become lone point spheres. Hole faces are labelled as boundary.
std::vector<VertexId> insert_rotation_system(
    Dlfl& dlfl, const RotationSystem& rs, std::span<const Dlfl::Vec3> positions,
    const InsertOptions& options, ScratchVector<CornerId>* corner_of_half_edge = nullptr);

/// The same result as insert_rotation_system() written in one linear pass (no operator calls).
/// Not for join_vertices (their existing edges are found only by the operators).
std::vector<VertexId> assemble_rotation_system(
    Dlfl& dlfl, const RotationSystem& rs, std::span<const Dlfl::Vec3> positions,
    const InsertOptions& options, ScratchVector<CornerId>* corner_of_half_edge = nullptr);

}  // namespace bisturi::construction
