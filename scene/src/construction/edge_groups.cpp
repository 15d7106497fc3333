#include "edge_groups.h"

#include <algorithm>

namespace bisturi::construction {

EdgeGroups group_edges(std::span<const std::uint32_t> from, std::span<const std::uint32_t> to,
                       std::size_t vertex_count) {
  const std::size_t nh = from.size();
  ScratchVector<std::uint32_t> bucket_start(vertex_count + 1, 0);
  for (std::size_t h = 0; h < nh; ++h)
    ++bucket_start[std::min(from[h], to[h]) + 1];
  for (std::size_t v = 0; v < vertex_count; ++v)
    bucket_start[v + 1] += bucket_start[v];
  ScratchVector<std::uint32_t> sorted(nh);
  {
    ScratchVector<std::uint32_t> fill(bucket_start.begin(), bucket_start.end() - 1);
    for (std::uint32_t h = 0; h < nh; ++h)
      sorted[fill[std::min(from[h], to[h])]++] = h;
  }
  EdgeGroups g;
  g.group_of.resize(nh);
  g.members.reserve(nh);
  g.offsets.reserve(nh / 2 + 2);
  g.offsets.push_back(0);
  auto other_end = [&](std::uint32_t h) { return std::max(from[h], to[h]); };
  for (std::size_t v = 0; v < vertex_count; ++v) {
    auto first = sorted.begin() + bucket_start[v];
    auto last = sorted.begin() + bucket_start[v + 1];
    // Buckets hold a vertex's few edges: an insertion sort, stable so the sides of one edge
    // keep input order (the first face first), and no allocation.
    for (auto it = first; it != last; ++it) {
      const std::uint32_t h = *it;
      auto hole = it;
      while (hole != first && other_end(*(hole - 1)) > other_end(h)) {
        *hole = *(hole - 1);
        --hole;
      }
      *hole = h;
    }
    for (auto it = first; it != last; ++it) {
      if (it != first && other_end(*it) != other_end(*(it - 1))) {
        g.offsets.push_back(static_cast<std::uint32_t>(g.members.size()));
      }
      g.group_of[*it] = static_cast<std::uint32_t>(g.offsets.size() - 1);
      g.members.push_back(*it);
    }
    if (first != last) g.offsets.push_back(static_cast<std::uint32_t>(g.members.size()));
  }
  return g;
}

}  // namespace bisturi::construction
