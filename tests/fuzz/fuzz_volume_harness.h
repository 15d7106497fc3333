#pragma once
// One fuzz input through a volume reader: an InputError naming the file is the only allowed
// failure, and a volume that comes back must be whole (sizes, value count, a valid geometry).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/volume_io.h"

namespace bisturi::fuzz {

[[noreturn]] inline void volume_broken(const char* what) {
  std::fprintf(stderr, "volume reader invariant broken: %s\n", what);
  std::abort();
}

inline void check_volume(const Volume& v) {
  const VolumeGeometry& g = v.geometry;
  for (int a = 0; a < 3; ++a) {
    if (g.dims[static_cast<std::size_t>(a)] < 1) volume_broken("a size below 1");
    if (!(g.spacing[a] > 0.0) || !std::isfinite(g.spacing[a])) volume_broken("spacing");
    if (!std::isfinite(g.origin[a])) volume_broken("origin not finite");
    for (int b = 0; b < 3; ++b) {
      const double d = glm::dot(g.direction[a], g.direction[b]);
      if (!(std::abs(d - (a == b ? 1.0 : 0.0)) < 1e-9)) volume_broken("direction not orthonormal");
    }
  }
  if (v.values.size() != g.voxel_count()) volume_broken("value count");
  (void)value_range(v);
}

template <class Read>
int run_volume(const std::uint8_t* data, std::size_t size, Read read) {
  const std::string name = "fuzz-input";
  try {
    check_volume(read(std::span(reinterpret_cast<const std::byte*>(data), size), name));
  } catch (const InputError& e) {
    if (std::string(e.what()).rfind(name + ": ", 0) != 0) {
      volume_broken("the message does not name the file");
    }
  }
  return 0;
}

}  // namespace bisturi::fuzz
