#pragma once
// Unaligned loads and stores of scalars in a given byte order.

#include <algorithm>
#include <bit>
#include <cstddef>
#include <cstring>

namespace bisturi::mesh_io {

/// True when data in little-endian (or big-endian) order must be byte-swapped on this machine.
constexpr bool swap_for(bool little_endian) {
  return little_endian != (std::endian::native == std::endian::little);
}

template <class T>
T load(const std::byte* p, bool swap) {
  std::byte b[sizeof(T)];
  std::memcpy(b, p, sizeof(T));
  if (swap) std::reverse(b, b + sizeof(T));
  T v;
  std::memcpy(&v, b, sizeof(T));
  return v;
}

template <class T>
void store(std::byte* p, T v, bool swap) {
  std::memcpy(p, &v, sizeof(T));
  if (swap) std::reverse(p, p + sizeof(T));
}

}  // namespace bisturi::mesh_io
