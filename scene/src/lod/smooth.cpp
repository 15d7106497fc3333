// Taubin smoothing over a compressed neighbour table built once from the rotations.

#include "bisturi/scene/lod/smooth.h"

#include <cstdint>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"

namespace bisturi::lod {

SmoothStats smooth_taubin(Dlfl& mesh, const SmoothOptions& options) {
  if (!(options.lambda > 0.0) || !(options.mu < -options.lambda)) {
    throw InputError("smooth_taubin: need lambda > 0 and mu < -lambda (got lambda " +
                     std::to_string(options.lambda) + ", mu " + std::to_string(options.mu) + ")");
  }
  using Vec3 = Dlfl::Vec3;
  const std::size_t n = mesh.vertex_capacity();
  // Free vertices and their neighbours (CSR).
  std::vector<std::uint32_t> movable;
  std::vector<std::uint32_t> offsets{0};
  std::vector<std::uint32_t> adjacency;
  SmoothStats stats;
  const auto& labels = mesh.bounding_labels();
  for (std::uint32_t v = 0; v < n; ++v) {
    const VertexId x(v);
    if (!mesh.alive(x)) continue;
    const RotationId first = mesh.first_rotation(x);
    bool fixed = options.fix_junctions && mesh.next_rotation(first).valid();
    const std::size_t begin = adjacency.size();
    for (RotationId r = first; r.valid() && !fixed; r = mesh.next_rotation(r)) {
      const CornerId start = mesh.rotation_corner(r);
      CornerId c = start;
      do {
        if (options.fix_boundary && labels[mesh.face(c).idx] != 0) {
          fixed = true;
          break;
        }
        if (!mesh.is_point_sphere(c)) adjacency.push_back(mesh.vertex(mesh.next(c)).idx);
        c = mesh.rot_next(c);
      } while (c != start);
    }
    if (fixed || adjacency.size() == begin) {
      adjacency.resize(begin);
      ++stats.fixed_vertices;
      continue;
    }
    movable.push_back(v);
    offsets.push_back(static_cast<std::uint32_t>(adjacency.size()));
  }
  stats.moved_vertices = movable.size();

  auto& pos = mesh.positions();
  std::vector<Vec3> moved(movable.size());
  auto step = [&](double factor) {
    for (std::size_t i = 0; i < movable.size(); ++i) {
      Vec3 sum(0.0);
      for (std::uint32_t k = offsets[i]; k < offsets[i + 1]; ++k)
        sum += pos[adjacency[k]];
      const double count = static_cast<double>(offsets[i + 1] - offsets[i]);
      const Vec3& p = pos[movable[i]];
      moved[i] = p + factor * (sum / count - p);
    }
    for (std::size_t i = 0; i < movable.size(); ++i)
      pos[movable[i]] = moved[i];
  };
  for (std::size_t it = 0; it < options.iterations; ++it) {
    step(options.lambda);
    step(options.mu);
    if (options.progress) options.progress(it + 1, options.iterations);
  }
  return stats;
}

}  // namespace bisturi::lod
