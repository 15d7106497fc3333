#include "bisturi/runtime/render/chunk_tree.h"

#include <algorithm>

namespace bisturi::render {

namespace {

/// A triangle and its centroid side by side: the splits compare and move them in place rather
/// than looking each centroid up by the triangle's id.
struct Item {
  glm::vec3 centroid;
  std::uint32_t triangle;
};

struct Builder {
  std::vector<Item> items;
  std::uint32_t max_triangles;
  ChunkTree tree;

  std::int32_t build(std::size_t begin, std::size_t end) {
    const auto node_index = static_cast<std::int32_t>(tree.nodes.size());
    tree.nodes.emplace_back();
    const auto first_chunk = static_cast<std::uint32_t>(tree.chunks.size());
    if (end - begin <= max_triangles) {
      Chunk chunk;
      chunk.first_index = static_cast<std::uint32_t>(begin * 3);
      chunk.index_count = static_cast<std::uint32_t>((end - begin) * 3);
      tree.chunks.push_back(chunk);
    } else {
      glm::vec3 lo(std::numeric_limits<float>::infinity());
      glm::vec3 hi(-std::numeric_limits<float>::infinity());
      for (std::size_t i = begin; i < end; ++i) {
        lo = glm::min(lo, items[i].centroid);
        hi = glm::max(hi, items[i].centroid);
      }
      const glm::vec3 extent = hi - lo;
      const int axis =
          extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
      const std::size_t mid = begin + (end - begin) / 2;
      std::nth_element(
          items.begin() + static_cast<std::ptrdiff_t>(begin),
          items.begin() + static_cast<std::ptrdiff_t>(mid),
          items.begin() + static_cast<std::ptrdiff_t>(end),
          [axis](const Item& a, const Item& b) { return a.centroid[axis] < b.centroid[axis]; });
      const std::int32_t left = build(begin, mid);
      const std::int32_t right = build(mid, end);
      tree.nodes[static_cast<std::size_t>(node_index)].left = left;
      tree.nodes[static_cast<std::size_t>(node_index)].right = right;
    }
    ChunkNode& node = tree.nodes[static_cast<std::size_t>(node_index)];
    node.first_chunk = first_chunk;
    node.chunk_count = static_cast<std::uint32_t>(tree.chunks.size()) - first_chunk;
    return node_index;
  }
};

}  // namespace

void ChunkTree::refit(std::span<const glm::vec3> positions,
                      std::span<const std::uint32_t> indices) {
  for (Chunk& chunk : chunks) {
    Aabb box;
    glm::vec3 lo(std::numeric_limits<float>::infinity());
    glm::vec3 hi(-std::numeric_limits<float>::infinity());
    const std::uint32_t end = chunk.first_index + chunk.index_count;
    for (std::uint32_t i = chunk.first_index; i < end; ++i) {
      const glm::vec3& p = positions[indices[i]];
      lo = glm::min(lo, p);
      hi = glm::max(hi, p);
    }
    if (chunk.index_count > 0) {
      box.lo = glm::dvec3(lo);
      box.hi = glm::dvec3(hi);
    }
    chunk.bounds = box;
  }
  // Children follow their parent in `nodes`, so a backward pass sees children first.
  for (std::size_t n = nodes.size(); n-- > 0;) {
    ChunkNode& node = nodes[n];
    Aabb box;
    if (node.left < 0) {
      for (std::uint32_t c = 0; c < node.chunk_count; ++c)
        box.extend(chunks[node.first_chunk + c].bounds);
    } else {
      box.extend(nodes[static_cast<std::size_t>(node.left)].bounds);
      box.extend(nodes[static_cast<std::size_t>(node.right)].bounds);
    }
    node.bounds = box;
  }
}

ChunkTree build_chunk_tree(std::span<const glm::vec3> positions,
                           std::vector<std::uint32_t>& indices, std::uint32_t max_triangles) {
  const std::size_t triangles = indices.size() / 3;
  Builder b{{}, std::max<std::uint32_t>(1, max_triangles), {}};
  if (triangles == 0) return {};
  b.items.resize(triangles);
  for (std::size_t t = 0; t < triangles; ++t) {
    b.items[t].centroid = (positions[indices[3 * t]] + positions[indices[3 * t + 1]] +
                           positions[indices[3 * t + 2]]) /
                          3.0f;
    b.items[t].triangle = static_cast<std::uint32_t>(t);
  }
  b.build(0, triangles);
  std::vector<std::uint32_t> sorted(indices.size());
  for (std::size_t i = 0; i < triangles; ++i) {
    for (std::size_t k = 0; k < 3; ++k)
      sorted[3 * i + k] = indices[3 * std::size_t{b.items[i].triangle} + k];
  }
  indices.swap(sorted);
  b.tree.refit(positions, indices);
  return std::move(b.tree);
}

}  // namespace bisturi::render
