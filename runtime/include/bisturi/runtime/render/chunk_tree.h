#pragma once
// Spatial chunks of a triangle list for culling: the triangles are reordered so that each chunk
// is one contiguous index range (one draw call, or none when culled), and the chunks are the
// leaves of a binary tree (median splits of triangle centroids along the longest axis) whose node
// boxes are refitted, not rebuilt, when the mesh deforms.

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/runtime/render/frustum.h"

namespace bisturi::render {

struct Chunk {
  std::uint32_t first_index = 0;
  std::uint32_t index_count = 0;
  Aabb bounds;
};

struct ChunkNode {
  Aabb bounds;
  std::uint32_t first_chunk = 0;  ///< the node's chunks are [first_chunk, first_chunk + count)
  std::uint32_t chunk_count = 0;
  std::int32_t left = -1;  ///< child nodes; -1 for a leaf (one chunk)
  std::int32_t right = -1;
};

struct ChunkTree {
  std::vector<Chunk> chunks;
  std::vector<ChunkNode> nodes;  ///< nodes[0] is the root (when there is any triangle)

  /// Recomputes every chunk and node box from the current positions (a refit: O(indices)).
  void refit(std::span<const glm::vec3> positions, std::span<const std::uint32_t> indices);
};

/// Reorders the triangles of `indices` (three per triangle) into chunks of at most
/// `max_triangles` and returns their tree, boxes fitted to `positions`.
ChunkTree build_chunk_tree(std::span<const glm::vec3> positions,
                           std::vector<std::uint32_t>& indices, std::uint32_t max_triangles);

}  // namespace bisturi::render
