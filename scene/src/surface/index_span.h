#pragma once
// Marching cubes (marching_cubes.cpp): intervals of sample or cell indices along x, and the bits
// they cover in the 64-sample words of a classified row.

#include <algorithm>
#include <cstdint>

namespace bisturi::surface {

/// An interval of indices [lo, hi); empty when lo >= hi.
struct Span {
  std::int32_t lo = 0;
  std::int32_t hi = 0;
  [[nodiscard]] bool empty() const { return lo >= hi; }
  void unite(Span o) {
    if (o.empty()) return;
    if (empty()) {
      *this = o;
    } else {
      lo = std::min(lo, o.lo);
      hi = std::max(hi, o.hi);
    }
  }
  [[nodiscard]] Span intersect(Span o) const { return {std::max(lo, o.lo), std::min(hi, o.hi)}; }
};

/// Bits [lo, hi) of word w (sample indices), hi > lo allowed to fall outside the word.
inline std::uint64_t range_mask(std::int64_t w, std::int64_t lo, std::int64_t hi) {
  const std::int64_t base = 64 * w;
  const std::int64_t a = std::clamp<std::int64_t>(lo - base, 0, 64);
  const std::int64_t b = std::clamp<std::int64_t>(hi - base, 0, 64);
  if (b <= a) return 0;
  const std::uint64_t upper = b == 64 ? ~std::uint64_t{0} : (std::uint64_t{1} << b) - 1;
  const std::uint64_t lower = (std::uint64_t{1} << a) - 1;
  return upper & ~lower;
}

}  // namespace bisturi::surface
