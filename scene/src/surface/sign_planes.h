#pragma once
// Marching cubes (marching_cubes.cpp): the inside/outside classification of the sample planes,
// one bit per sample (bit i of row j: sample (i, j) is inside, value > iso). Each plane is
// classified once; the crossed edges and the mixed cells are then found with bit operations on
// these rows (crossing_walks.h), 64 samples at a time.
//
// The mesh pass keeps two planes (the current slab's), the DLFL build keeps every plane so that
// its second pass need not read the volume again. Plane z lives in slot z % kept, so a slot is
// reused: only the samples in a row's `classified` span are valid for the current plane.

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/volume/volume.h"
#include "index_span.h"
#include "visited_cells.h"

namespace bisturi::surface {

class SignPlanes {
 public:
  /// The rows of one classified plane (a read-only view).
  struct Plane {
    const std::uint64_t* bits;  ///< row j: the words bits + j * stride (one padding word after)
    const Span* classified;     ///< per row: the samples classified for this plane, whole words
    std::int64_t stride;
    std::int64_t rows;  ///< the samples along y
    [[nodiscard]] const std::uint64_t* row(std::int64_t j) const { return bits + j * stride; }
  };

  SignPlanes(const Grid<float>& volume, float iso)
      : values_(volume.values.data()),
        iso_(iso),
        nx_(volume.geometry.dims[0]),
        ny_(volume.geometry.dims[1]),
        plane_(nx_ * ny_),
        // One zero word of padding: reading word w + 1 of a row is always valid.
        row_stride_((nx_ + 63) / 64 + 1) {}

  /// Makes room for `kept` planes, all bits clear.
  void allocate(std::int64_t kept) {
    planes_kept_ = kept;
    bits_.assign(static_cast<std::size_t>(kept * ny_ * row_stride_), 0);
    classified_.assign(static_cast<std::size_t>(kept * ny_), Span{});
  }

  [[nodiscard]] Plane plane(std::int64_t z) const {
    const std::int64_t slot = z % planes_kept_;
    return {bits_.data() + slot * ny_ * row_stride_, classified_.data() + slot * ny_, row_stride_,
            ny_};
  }

  /// Classifies the words of sample plane z that the visited cells touch.
  void classify(std::int64_t z, const VisitedCells& visited) {
    const std::int64_t slot = z % planes_kept_;
    std::uint64_t* plane_bits = bits_.data() + slot * ny_ * row_stride_;
    Span* plane_classified = classified_.data() + slot * ny_;
    for (std::int64_t j = 0; j < ny_; ++j) {
      const Span s = visited.samples(j, z);
      std::uint64_t* row = plane_bits + j * row_stride_;
      if (s.empty()) {
        plane_classified[j] = {};
        continue;
      }
      const std::int64_t w0 = s.lo / 64, w1 = (std::min<std::int64_t>(s.hi, nx_) + 63) / 64;
      plane_classified[j] = {static_cast<std::int32_t>(64 * w0),
                             static_cast<std::int32_t>(std::min<std::int64_t>(64 * w1, nx_))};
      const float* v = values_ + z * plane_ + j * nx_;
      for (std::int64_t w = w0; w < w1; ++w) {
        const std::int64_t i0 = 64 * w;
        const std::int64_t n = std::min<std::int64_t>(64, nx_ - i0);
        row[w] = n == 64 ? classify64(v + i0) : classify_tail(v + i0, n);
      }
    }
  }

 private:
  /// 64 samples into one word. The comparisons go to bytes first so that the loop vectorises.
  [[nodiscard]] std::uint64_t classify64(const float* v) const {
    std::array<std::uint8_t, 64> flags;
    const float iso = iso_;
    for (std::size_t b = 0; b < 64; ++b)
      flags[b] = static_cast<std::uint8_t>(v[b] > iso);
    std::uint64_t word = 0;
    for (std::size_t g = 0; g < 8; ++g) {
      std::uint64_t eight;
      std::memcpy(&eight, flags.data() + 8 * g, 8);
      // Gathers the low bit of each byte into the top byte (little-endian byte order).
      word |= ((eight * 0x0102040810204080ULL) >> 56) << (8 * g);
    }
    return word;
  }

  /// The last n < 64 samples of a row.
  [[nodiscard]] std::uint64_t classify_tail(const float* v, std::int64_t n) const {
    std::uint64_t word = 0;
    for (std::int64_t b = 0; b < n; ++b) {
      word |= static_cast<std::uint64_t>(v[b] > iso_ ? 1 : 0) << b;
    }
    return word;
  }

  const float* values_;
  float iso_;
  std::int64_t nx_, ny_, plane_, row_stride_;
  std::int64_t planes_kept_ = 2;
  ScratchVector<std::uint64_t> bits_;  // per kept plane: ny rows of row_stride words
  ScratchVector<Span> classified_;     // per kept plane and sample row: the classified samples
};

}  // namespace bisturi::surface
