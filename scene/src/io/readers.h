#pragma once
// The format readers behind read_mesh_from_memory. Each one gets the whole file image and the
// name to put in messages, and either returns the complete mesh or throws InputError.

#include <cstddef>
#include <cstdint>
#include <limits>
#include <span>
#include <string>
#include <string_view>

#include "bisturi/scene/io/mesh_file.h"

namespace bisturi::mesh_io {

MeshFile read_obj(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options);
MeshFile read_ply(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options);
MeshFile read_stl(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options);
MeshFile read_off(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options);

inline std::string_view as_text(std::span<const std::byte> data) {
  return {reinterpret_cast<const char*>(data.data()), data.size()};
}

/// PolygonMesh indexes with uint32: the most vertices, and corners in all faces, a file may hold.
constexpr std::uint64_t kMaxIndex = std::numeric_limits<std::uint32_t>::max();

/// Ends the face whose indices were just appended; false when the corners no longer fit uint32.
inline bool close_face(PolygonMesh& mesh) {
  if (mesh.indices.size() > kMaxIndex) return false;
  mesh.offsets.push_back(static_cast<std::uint32_t>(mesh.indices.size()));
  return true;
}

}  // namespace bisturi::mesh_io
