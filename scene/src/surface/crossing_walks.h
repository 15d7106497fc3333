#pragma once
// Marching cubes (marching_cubes.cpp): the walks over the sign bits of the classified planes
// (sign_planes.h). An edge is crossed where its two samples' bits differ, a cell is mixed where its
// eight corners' bits are neither all 0 nor all 1; both are found a word (64 edges or cells) at a
// time. Only samples classified for the current plane are compared: the others are stale.

#include <cstdint>

#include "index_span.h"
#include "sign_planes.h"

namespace bisturi::surface {

/// Calls fn(axis, j, w, crossed) for each word of crossed x-edges (axis 0, samples (i, i+1) of
/// row j) and y-edges (axis 1, rows j and j+1) of a sample plane; bit b of `crossed` is the edge
/// whose lower sample is i = 64 w + b.
template <class Fn>
void for_each_plane_crossing(const SignPlanes::Plane& plane, Fn&& fn) {
  for (std::int64_t j = 0; j < plane.rows; ++j) {
    const std::uint64_t* row = plane.row(j);
    // x-edges (i, i+1): both samples classified.
    const Span xs{plane.classified[j].lo, plane.classified[j].hi - 1};
    if (!xs.empty()) {
      for (std::int64_t w = xs.lo / 64; w * 64 < xs.hi; ++w) {
        fn(0, j, w, (row[w] ^ ((row[w] >> 1) | (row[w + 1] << 63))) & range_mask(w, xs.lo, xs.hi));
      }
    }
    if (j + 1 >= plane.rows) continue;
    const Span ys = plane.classified[j].intersect(plane.classified[j + 1]);
    if (ys.empty()) continue;
    const std::uint64_t* up = row + plane.stride;
    for (std::int64_t w = ys.lo / 64; w * 64 < ys.hi; ++w) {
      fn(1, j, w, (row[w] ^ up[w]) & range_mask(w, ys.lo, ys.hi));
    }
  }
}

/// Calls fn(j, w, crossed) for each word of crossed z-edges between two consecutive planes.
template <class Fn>
void for_each_slab_crossing(const SignPlanes::Plane& lower, const SignPlanes::Plane& upper,
                            Fn&& fn) {
  for (std::int64_t j = 0; j < lower.rows; ++j) {
    const Span zs = lower.classified[j].intersect(upper.classified[j]);
    if (zs.empty()) continue;
    const std::uint64_t* r0 = lower.row(j);
    const std::uint64_t* r1 = upper.row(j);
    for (std::int64_t w = zs.lo / 64; w * 64 < zs.hi; ++w) {
      fn(j, w, (r0[w] ^ r1[w]) & range_mask(w, zs.lo, zs.hi));
    }
  }
}

/// Calls fn(config, i) for the mixed cells i in [cells.lo, cells.hi) of cell row j between two
/// consecutive planes, in order; bit c of `config` is corner c (cube_cases.h) inside.
template <class Fn>
void for_each_mixed_cell(const SignPlanes::Plane& lower, const SignPlanes::Plane& upper,
                         std::int64_t j, Span cells, Fn&& fn) {
  // Rows by (y, z) offset of the corners; the s* words below are the same rows shifted by one
  // sample, so bit b holds corner x = 1 of cell b.
  const std::uint64_t* r00 = lower.row(j);
  const std::uint64_t* r10 = r00 + lower.stride;
  const std::uint64_t* r01 = upper.row(j);
  const std::uint64_t* r11 = r01 + upper.stride;
  for (std::int64_t w = cells.lo / 64; w * 64 < cells.hi; ++w) {
    const std::uint64_t a00 = r00[w], a10 = r10[w], a01 = r01[w], a11 = r11[w];
    const std::uint64_t s00 = (a00 >> 1) | (r00[w + 1] << 63);
    const std::uint64_t s10 = (a10 >> 1) | (r10[w + 1] << 63);
    const std::uint64_t s01 = (a01 >> 1) | (r01[w + 1] << 63);
    const std::uint64_t s11 = (a11 >> 1) | (r11[w + 1] << 63);
    const std::uint64_t any = a00 | a10 | a01 | a11 | s00 | s10 | s01 | s11;
    const std::uint64_t all = a00 & a10 & a01 & a11 & s00 & s10 & s01 & s11;
    std::uint64_t mixed = any & ~all & range_mask(w, cells.lo, cells.hi);
    while (mixed != 0) {
      const int b = __builtin_ctzll(mixed);
      mixed &= mixed - 1;
      const auto config = static_cast<unsigned>(((a00 >> b) & 1) | (((s00 >> b) & 1) << 1) |
                                                (((a10 >> b) & 1) << 2) | (((s10 >> b) & 1) << 3) |
                                                (((a01 >> b) & 1) << 4) | (((s01 >> b) & 1) << 5) |
                                                (((a11 >> b) & 1) << 6) | (((s11 >> b) & 1) << 7));
      fn(config, 64 * w + b);
    }
  }
}

}  // namespace bisturi::surface
