#include "mesh_check.h"

#include <algorithm>
#include <cmath>

#include "bisturi/scene/errors.h"
#include "parse_errors.h"
#include "readers.h"

namespace bisturi::mesh_io {

void check_writable(const PolygonMesh& mesh, const std::string& file) {
  const auto fail = [&](const std::string& what) {
    throw InputError(cat(file, ": cannot write the mesh: ", what));
  };
  if (mesh.positions.size() > kMaxIndex) fail("more vertices than 32-bit indices can address");
  for (std::size_t v = 0; v < mesh.positions.size(); ++v) {
    const auto& p = mesh.positions[v];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)) {
      fail(cat("vertex ", v, ": a coordinate is not finite"));
    }
  }
  if (mesh.offsets.empty() || mesh.offsets.front() != 0 ||
      mesh.offsets.back() != mesh.indices.size()) {
    fail("the face offsets do not match the index list");
  }
  // Offsets first: once they rise strictly to the index count, every face lies inside it.
  for (std::size_t f = 0; f + 1 < mesh.offsets.size(); ++f) {
    if (mesh.offsets[f + 1] <= mesh.offsets[f]) {
      fail(
          cat("face ", f,
              mesh.offsets[f + 1] == mesh.offsets[f] ? ": no vertex index" : ": offsets decrease"));
    }
  }
  for (std::size_t f = 0; f + 1 < mesh.offsets.size(); ++f) {
    for (const std::uint32_t i : mesh.face(f)) {
      if (i >= mesh.positions.size()) {
        fail(cat("face ", f, ": vertex index ", i, " out of range (", mesh.positions.size(),
                 " vertices)"));
      }
    }
  }
}

std::size_t max_face_size(const PolygonMesh& mesh) {
  std::size_t m = 0;
  for (std::size_t f = 0; f + 1 < mesh.offsets.size(); ++f) {
    m = std::max<std::size_t>(m, mesh.offsets[f + 1] - mesh.offsets[f]);
  }
  return m;
}

}  // namespace bisturi::mesh_io
