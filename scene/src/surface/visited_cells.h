#pragma once
// Marching cubes (marching_cubes.cpp): which cells the extraction visits. Without an octree every
// cell; with one only the cells of leaves whose value range holds the iso value, kept per cell row
// as one x-range (the union of the leaves' ranges: a row is walked from its first to its last
// visited cell, which keeps the walk a plain bit scan). The sample planes are classified only
// where these cells need it.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <vector>

#include "bisturi/scene/volume/bono_octree.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "index_span.h"

namespace bisturi::surface {

class VisitedCells {
 public:
  explicit VisitedCells(const std::array<std::int64_t, 3>& dims)
      : nx_(dims[0]), ny_(dims[1]), nz_(dims[2]) {}

  /// Restricts the visited cells to the leaves of `octree` whose range holds `iso`; counts the
  /// leaves visited and skipped into `stats`.
  void restrict_to(const BonoOctree& octree, float iso, ExtractionStats& stats) {
    cell_rows_.assign(static_cast<std::size_t>((ny_ - 1) * (nz_ - 1)), Span{});
    std::size_t visited = 0;
    octree.for_each_leaf_in_range(iso, iso, [&](const BonoOctree::Node& n) {
      ++visited;
      const auto& o = n.box.origin;
      const auto& s = n.box.size;
      const Span xs{static_cast<std::int32_t>(o[0]),
                    static_cast<std::int32_t>(std::min(o[0] + s[0], nx_ - 1))};
      if (xs.empty()) return;
      const std::int64_t j1 = std::min(o[1] + s[1], ny_ - 1);
      const std::int64_t k1 = std::min(o[2] + s[2], nz_ - 1);
      for (std::int64_t k = o[2]; k < k1; ++k) {
        for (std::int64_t j = o[1]; j < j1; ++j) {
          cell_rows_[static_cast<std::size_t>(k * (ny_ - 1) + j)].unite(xs);
        }
      }
    });
    stats.leaves_visited = visited;
    stats.leaves_skipped = octree.leaf_count() - visited;
  }

  /// The visited cells of cell row (j, k); empty outside the volume.
  [[nodiscard]] Span cells(std::int64_t j, std::int64_t k) const {
    if (j < 0 || k < 0 || j >= ny_ - 1 || k >= nz_ - 1) return {};
    if (cell_rows_.empty()) return {0, static_cast<std::int32_t>(nx_ - 1)};
    return cell_rows_[static_cast<std::size_t>(k * (ny_ - 1) + j)];
  }

  /// The samples of row j of plane z that must be classified: those of the (up to four) cell rows
  /// that touch it, plus one in x (a cell's upper corners).
  [[nodiscard]] Span samples(std::int64_t j, std::int64_t z) const {
    Span s;
    for (std::int64_t dj = -1; dj <= 0; ++dj) {
      for (std::int64_t dz = -1; dz <= 0; ++dz)
        s.unite(cells(j + dj, z + dz));
    }
    if (!s.empty()) s.hi += 1;
    return s;
  }

 private:
  std::int64_t nx_, ny_, nz_;
  std::vector<Span> cell_rows_;  // empty: every cell row is visited whole
};

}  // namespace bisturi::surface
