#pragma once
// One fuzz input through a mesh reader: an InputError naming the file is the only allowed
// failure, and a mesh that comes back must be whole (offsets, indices, finite positions).

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"

namespace bisturi::fuzz {

[[noreturn]] inline void broken(const char* what) {
  std::fprintf(stderr, "mesh reader invariant broken: %s\n", what);
  std::abort();
}

inline void check_mesh(const MeshFile& file, std::size_t size) {
  const PolygonMesh& m = file.polygons;
  if (file.source_bytes != size) broken("source_bytes");
  if (m.offsets.empty() || m.offsets.front() != 0 || m.offsets.back() != m.indices.size()) {
    broken("offsets do not frame the index list");
  }
  for (std::size_t f = 0; f + 1 < m.offsets.size(); ++f) {
    if (m.offsets[f + 1] <= m.offsets[f]) broken("an empty or reversed face");
  }
  for (const std::uint32_t i : m.indices) {
    if (i >= m.positions.size()) broken("an index out of range");
  }
  for (const auto& p : m.positions) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) broken("not finite");
  }
  if (!file.has_vertex_list && m.indices.size() != m.positions.size()) broken("soup");
}

inline int run_one(const std::uint8_t* data, std::size_t size, MeshFormat format) {
  const std::string name = "fuzz-input";
  try {
    const MeshFile file = read_mesh_from_memory(
        std::span(reinterpret_cast<const std::byte*>(data), size), format, name);
    check_mesh(file, size);
  } catch (const InputError& e) {
    if (std::string(e.what()).rfind(name + ": ", 0) != 0) {
      broken("the message does not name the file");
    }
  }
  return 0;
}

}  // namespace bisturi::fuzz
