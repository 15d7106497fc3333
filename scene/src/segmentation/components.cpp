// Connected components: runs of nonzero voxels along i, joined with union-find to the runs of the
// already scanned neighbouring rows, then labelled in memory order.

#include <algorithm>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/segmentation.h"
#include "checks.h"

namespace bisturi {

namespace {

struct Run {
  std::int64_t begin;  // i of the first voxel
  std::int64_t end;    // one past the last
};

// Union-find over run indices; the root is the smallest index (the first run in memory order).
std::uint32_t find_root(ScratchVector<std::uint32_t>& parent, std::uint32_t x) {
  std::uint32_t root = x;
  while (parent[root] != root)
    root = parent[root];
  while (parent[x] != root) {
    const std::uint32_t next = parent[x];
    parent[x] = root;
    x = next;
  }
  return root;
}

void unite(ScratchVector<std::uint32_t>& parent, std::uint32_t a, std::uint32_t b) {
  a = find_root(parent, a);
  b = find_root(parent, b);
  if (a == b) return;
  if (a < b) {
    parent[b] = a;
  } else {
    parent[a] = b;
  }
}

}  // namespace

Components label_components(const Grid<std::uint8_t>& mask, Connectivity connectivity,
                            const ComponentOptions& options) {
  segmentation_detail::check_grid(mask, "connected components");
  const auto& dims = mask.geometry.dims;
  const std::int64_t nx = dims[0];
  const std::int64_t rows = dims[1] * dims[2];
  const std::uint8_t* data = mask.values.data();

  // 1. Runs, row by row (row r = j + ny * k): counted first, so that the arrays are allocated
  // once (growing them costs copies and page faults that dominate on noisy masks).
  std::vector<std::size_t> row_start(static_cast<std::size_t>(rows) + 1, 0);
  std::size_t run_count = 0;
  for (std::int64_t r = 0; r < rows; ++r) {
    row_start[static_cast<std::size_t>(r)] = run_count;
    const std::uint8_t* row = data + r * nx;
    std::size_t starts = row[0] != 0 ? 1 : 0;
    for (std::int64_t i = 1; i < nx; ++i)
      starts += (row[i] != 0 && row[i - 1] == 0) ? 1 : 0;
    run_count += starts;
  }
  row_start[static_cast<std::size_t>(rows)] = run_count;
  if (run_count >= std::numeric_limits<std::uint32_t>::max()) {
    throw InputError("connected components: more than 2^32 runs in the mask");
  }
  ScratchVector<Run> runs(run_count);
  for (std::int64_t r = 0; r < rows; ++r) {
    const std::uint8_t* row = data + r * nx;
    std::size_t x = row_start[static_cast<std::size_t>(r)];
    std::int64_t i = 0;
    while (i < nx) {
      while (i < nx && row[i] == 0)
        ++i;
      if (i == nx) break;
      const std::int64_t begin = i;
      while (i < nx && row[i] != 0)
        ++i;
      runs[x++] = {begin, i};
    }
  }

  // 2. Join each run to the overlapping runs of the earlier neighbouring rows.
  ScratchVector<std::uint32_t> parent(runs.size());
  for (std::size_t r = 0; r < runs.size(); ++r)
    parent[r] = static_cast<std::uint32_t>(r);
  const bool full = connectivity == Connectivity::TwentySix;
  // 26: the rows (j-1, k), (j-1, k-1), (j, k-1), (j+1, k-1), with runs touching diagonally.
  // 6: the rows (j-1, k) and (j, k-1), with runs sharing an i.
  struct Offset {
    std::int64_t dj, dk;
  };
  const std::vector<Offset> offsets = full
                                          ? std::vector<Offset>{{-1, 0}, {-1, -1}, {0, -1}, {1, -1}}
                                          : std::vector<Offset>{{-1, 0}, {0, -1}};
  const std::int64_t slack = full ? 1 : 0;
  for (std::int64_t k = 0; k < dims[2]; ++k) {
    for (std::int64_t j = 0; j < dims[1]; ++j) {
      const auto r = static_cast<std::size_t>(j + dims[1] * k);
      const std::size_t a_begin = row_start[r];
      const std::size_t a_end = row_start[r + 1];
      if (a_begin == a_end) continue;
      for (const Offset& o : offsets) {
        const std::int64_t oj = j + o.dj;
        const std::int64_t ok = k + o.dk;
        if (oj < 0 || ok < 0 || oj >= dims[1]) continue;
        const auto orow = static_cast<std::size_t>(oj + dims[1] * ok);
        std::size_t b = row_start[orow];
        const std::size_t b_end = row_start[orow + 1];
        std::size_t a = a_begin;
        while (a < a_end && b < b_end) {
          // Overlap of [begin - slack, end + slack) with the other run.
          if (runs[b].end + slack <= runs[a].begin) {
            ++b;
          } else if (runs[a].end + slack <= runs[b].begin) {
            ++a;
          } else {
            unite(parent, static_cast<std::uint32_t>(a), static_cast<std::uint32_t>(b));
            if (runs[a].end < runs[b].end) {
              ++a;
            } else {
              ++b;
            }
          }
        }
      }
    }
  }

  // 3. Provisional components in order of their first run, with counts and boxes.
  constexpr std::uint32_t kNone = std::numeric_limits<std::uint32_t>::max();
  ScratchVector<std::uint32_t> component_of_root(runs.size(), kNone);
  std::vector<ComponentStats> provisional;
  ScratchVector<std::uint32_t> run_component(runs.size());
  for (std::int64_t r = 0; r < rows; ++r) {
    const std::int64_t j = r % dims[1];
    const std::int64_t k = r / dims[1];
    for (std::size_t x = row_start[static_cast<std::size_t>(r)];
         x < row_start[static_cast<std::size_t>(r) + 1]; ++x) {
      const std::uint32_t root = find_root(parent, static_cast<std::uint32_t>(x));
      std::uint32_t& c = component_of_root[root];
      const Run& run = runs[x];
      if (c == kNone) {
        c = static_cast<std::uint32_t>(provisional.size());
        ComponentStats s;
        s.first_voxel = {run.begin, j, k};
        s.bounds.origin = {run.begin, j, k};
        s.bounds.size = {0, 1, 1};
        provisional.push_back(s);
      }
      run_component[x] = c;
      ComponentStats& s = provisional[c];
      s.voxel_count += run.end - run.begin;
      // Bounds as [origin, origin + size): grow to include [begin, end) x {j} x {k}.
      const std::array<std::int64_t, 3> lo{run.begin, j, k};
      const std::array<std::int64_t, 3> hi{run.end, j + 1, k + 1};
      for (int a = 0; a < 3; ++a) {
        const std::int64_t top = std::max(s.bounds.origin[a] + s.bounds.size[a], hi[a]);
        s.bounds.origin[a] = std::min(s.bounds.origin[a], lo[a]);
        s.bounds.size[a] = top - s.bounds.origin[a];
      }
    }
  }

  // 4. Drop small components; final labels keep the first-voxel order.
  std::vector<std::uint32_t> final_label(provisional.size(), 0);
  Components out;
  for (std::size_t c = 0; c < provisional.size(); ++c) {
    if (provisional[c].voxel_count < options.min_voxels) continue;
    final_label[c] = static_cast<std::uint32_t>(out.stats.size() + 1);
    out.stats.push_back(provisional[c]);
    out.stats.back().label = final_label[c];
  }
  out.labels.geometry = mask.geometry;
  out.labels.label_count = static_cast<std::uint32_t>(out.stats.size());
  out.labels.values.resize(mask.values.size());  // value-initialised: 0
  std::uint32_t* labels = out.labels.values.data();
  for (std::int64_t r = 0; r < rows; ++r) {
    std::uint32_t* row = labels + r * nx;
    for (std::size_t x = row_start[static_cast<std::size_t>(r)];
         x < row_start[static_cast<std::size_t>(r) + 1]; ++x) {
      const std::uint32_t l = final_label[run_component[x]];
      if (l != 0) std::fill(row + runs[x].begin, row + runs[x].end, l);
    }
  }
  return out;
}

}  // namespace bisturi
