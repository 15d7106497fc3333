#pragma once
// Internal: the half-edges of a polygon list grouped by undirected edge (same two vertices).

#include <cstdint>
#include <span>
#include <vector>
#include "bisturi/scene/big_vector.h"

namespace bisturi::construction {

struct EdgeGroups {
  ScratchVector<std::uint32_t> group_of;  ///< per half-edge
  ScratchVector<std::uint32_t> offsets;   ///< CSR over groups
  ScratchVector<std::uint32_t> members;   ///< half-edges, group by group

  [[nodiscard]] std::size_t count() const { return offsets.size() - 1; }
  [[nodiscard]] std::size_t size(std::uint32_t g) const { return offsets[g + 1] - offsets[g]; }
  [[nodiscard]] std::span<const std::uint32_t> of(std::uint32_t g) const {
    return {members.data() + offsets[g], size(g)};
  }
};

/// Groups half-edges (from[h], to[h]) by unordered vertex pair in linear time: a counting sort
/// on the smaller vertex, then a small sort inside each bucket.
EdgeGroups group_edges(std::span<const std::uint32_t> from, std::span<const std::uint32_t> to,
                       std::size_t vertex_count);

}  // namespace bisturi::construction
