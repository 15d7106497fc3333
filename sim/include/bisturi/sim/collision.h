#pragma once
// Collision on deforming soft bodies through Embree (kept private to sim: no Embree type in a
// public header). One SurfaceBvh per body: a two-level triangle BVH (one per patch of about 4096
// triangles, and a top level over them) refitted every step, only the patches whose vertices
// moved; when the body's topology version moves, the patches whose triangles changed much are
// rebuilt, the others keep their BVHs (see rebuild_changed in collision.cpp); closest-point and
// ray queries for the haptic proxy and the scalpel; and, on request, a user-geometry copy for
// rtcCollide (Embree's collide works on user geometry only) that finds the triangle pairs of
// tissue-tissue contact.

#include <cstdint>
#include <memory>
#include <utility>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

/// The Embree device shared by every BVH of a world. threads = 0 lets Embree pick; 1 keeps
/// builds on the calling thread (deterministic timing, no pool).
class CollisionDevice {
 public:
  explicit CollisionDevice(unsigned threads = 1);
  ~CollisionDevice();
  CollisionDevice(const CollisionDevice&) = delete;
  CollisionDevice& operator=(const CollisionDevice&) = delete;
  [[nodiscard]] void* handle() const { return device_; }  ///< RTCDevice

 private:
  void* device_ = nullptr;
};

struct SurfacePoint {
  bool found = false;
  glm::dvec3 point_m{0.0};
  glm::dvec3 normal{0.0};      ///< unit normal of the triangle, pointing out of the tissue
  double distance_m = 0.0;     ///< from the query point (closest point) or ray parameter (ray)
  std::uint32_t triangle = 0;  ///< index into the body's SurfaceTriangles
  glm::dvec3 barycentric{0.0};
};

/// When a topology change rebuilds a patch's BVH instead of keeping it with dead triangles.
struct PatchRebuildLimits {
  /// The loose patch holds at most this many triangles; past it every stale patch is rebuilt.
  std::size_t loose_triangles = 1024;
  /// A changed patch is rebuilt when more than this share of its primitives is dead or new.
  double stale_share = 0.125;
};

class SurfaceBvh {
 public:
  SurfaceBvh(const CollisionDevice& device, const SoftBody& body);
  ~SurfaceBvh();
  SurfaceBvh(SurfaceBvh&&) noexcept;
  SurfaceBvh& operator=(SurfaceBvh&&) noexcept;

  /// Refit to the body's positions, or rebuild when its topology version moved.
  void update(const SoftBody& body);
  [[nodiscard]] std::uint64_t rebuilds() const;
  [[nodiscard]] std::uint64_t refits() const;
  /// Patches of the two-level BVH (one Embree geometry each, about 4096 triangles, and the
  /// loose patch), and how many the last build or topology update rebuilt (the others were
  /// refitted).
  [[nodiscard]] std::size_t patch_count() const;
  [[nodiscard]] std::size_t last_rebuilt_patches() const;
  /// Patches the last update committed: on a refit, those with a vertex whose position (in
  /// float) moved (with a refit tolerance, those that drifted past it), 0 when none did; after
  /// a build or topology update, every non-empty one.
  [[nodiscard]] std::size_t last_refitted_patches() const;
  /// Triangles in the loose patch: those a cut added to patches it left unrebuilt (their BVHs
  /// keep the cut's dead triangles, which queries skip). Back to 0 when those are rebuilt.
  [[nodiscard]] std::size_t loose_triangles() const;
  void set_rebuild_limits(const PatchRebuildLimits& limits);
  /// Lazy refits: a patch whose vertices may have moved at most drift_m since its last refit
  /// waits (0, the default: every patch with a moved vertex is refitted at each update). The
  /// point queries stay exact (they widen their radius by the drift left); a ray refits the
  /// waiting patches first.
  void set_refit_tolerance(double drift_m);

  /// Closest surface point to p within max_distance_m (found = false when none).
  [[nodiscard]] SurfacePoint closest_point(const SoftBody& body, const glm::dvec3& p_m,
                                           double max_distance_m = 1e30) const;
  /// The triangles with a point within radius_m of p, sorted (the haptic contact patch).
  [[nodiscard]] std::vector<std::uint32_t> triangles_near(const SoftBody& body,
                                                          const glm::dvec3& p_m,
                                                          double radius_m) const;
  /// The same into `found` (cleared first), which keeps its capacity from call to call.
  void triangles_near(const SoftBody& body, const glm::dvec3& p_m, double radius_m,
                      std::vector<std::uint32_t>& found) const;
  /// First hit of the segment from -> to (found = false when none).
  [[nodiscard]] SurfacePoint ray(const SoftBody& body, const glm::dvec3& from_m,
                                 const glm::dvec3& to_m) const;
  /// A box holding the body's surface (the BVH's bounds, grown by the drift of the patches
  /// whose refits wait): lower and upper corners.
  [[nodiscard]] std::pair<glm::dvec3, glm::dvec3> bounds() const;
  /// Triangle pairs (this body's, other's) whose bounds overlap, sorted; bounds are grown by
  /// margin_m. Builds the user-geometry copies on first use.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> overlapping_triangles(
      const SoftBody& body, SurfaceBvh& other, const SoftBody& other_body, double margin_m);

  struct Impl;  // defined in collision.cpp (Embree's types stay there)

 private:
  std::unique_ptr<Impl> impl_;
};

/// Closest point on segment [a, b] to p (a where the two coincide), with its share of b in t.
glm::dvec3 closest_point_on_segment(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                    double& t);

/// Closest point on triangle (a, b, c) to p, with its barycentric coordinates in bc; on a
/// triangle without area, the closest point on its sides.
glm::dvec3 closest_point_on_triangle(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b,
                                     const glm::dvec3& c, glm::dvec3& bc);

}  // namespace bisturi::sim
