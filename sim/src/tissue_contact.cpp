// Tissue-tissue contact (see tissue_contact.h).

#include "bisturi/sim/tissue_contact.h"

#include <algorithm>
#include <limits>

#include <glm/geometric.hpp>

namespace bisturi::sim {

std::size_t push_out(SoftBody& from, PairSide side, const SoftBody& onto,
                     const SurfaceBvh& onto_bvh,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                     const ContactOptions& options, ContactScratch& scratch) {
  const auto& fi = from.triangles().indices;
  const auto& xf = from.positions();
  scratch.seen.assign(xf.size(), 0);
  scratch.vertices.clear();
  std::uint32_t last_triangle = std::numeric_limits<std::uint32_t>::max();
  for (const auto& pair : pairs) {
    const std::uint32_t tf = side == PairSide::First ? pair.first : pair.second;
    if (tf == last_triangle) continue;  // its vertices are in already
    last_triangle = tf;
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t v = fi[3 * std::size_t{tf} + c];
      if (scratch.seen[v] != 0) continue;
      scratch.seen[v] = 1;
      scratch.vertices.push_back(v);
    }
  }
  std::sort(scratch.vertices.begin(), scratch.vertices.end());
  const double reach = std::max(options.margin_m, options.max_depth_m);
  std::size_t contacts = 0;
  for (const std::uint32_t v : scratch.vertices) {
    if (from.mass(VertexId(v)) <= 0.0) continue;
    const glm::dvec3& p = xf[v];
    const SurfacePoint q = onto_bvh.closest_point(onto, p, reach);
    if (!q.found) continue;
    const double d = glm::dot(p - q.point_m, q.normal);  // < 0: inside `onto`
    if (d >= options.margin_m || -d > options.max_depth_m) continue;
    from.add_contact(VertexId(v), q.normal, options.margin_m - d, options.stiffness_N_per_m);
    ++contacts;
  }
  return contacts;
}

}  // namespace bisturi::sim
