#pragma once
// Tissue against tissue: the implicit penalty contacts that push one solid's surface out of
// another's (SimWorld's contact phase; docs/sim/collision.md).

#include <cstddef>
#include <cstdint>
#include <utility>
#include <vector>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

struct ContactOptions {
  bool enabled = true;
  double margin_m = 0.0005;  ///< contact starts this close to the other surface
  /// Penalty per vertex; implicit (SoftBody::add_contact), so it may be stiff.
  double stiffness_N_per_m = 200.0;
  /// Deeper than this a vertex is taken for a wrong pairing (the far side of a thin part), not
  /// a penetration, and left alone.
  double max_depth_m = 0.005;
};

/// Which triangle of each pair (SurfaceBvh::overlapping_triangles) is the pushed body's.
enum class PairSide : std::uint8_t { First, Second };

/// Reused between calls, so a step allocates nothing once it has grown.
struct ContactScratch {
  std::vector<std::uint8_t> seen;
  std::vector<std::uint32_t> vertices;
};

/// Each vertex of `from`'s triangles in `pairs` against the nearest point of `onto`'s surface
/// within max_depth_m (one query of onto's BVH per vertex, however many pairs it is in: a
/// vessel lying along an organ's coarse triangles is in tens of thousands): closer than the
/// margin along that triangle's outward normal, or inside, it gets a contact pushing it out.
/// Contacts are added in vertex order; returns how many.
std::size_t push_out(SoftBody& from, PairSide side, const SoftBody& onto,
                     const SurfaceBvh& onto_bvh,
                     const std::vector<std::pair<std::uint32_t, std::uint32_t>>& pairs,
                     const ContactOptions& options, ContactScratch& scratch);

}  // namespace bisturi::sim
