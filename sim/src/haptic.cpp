#include "bisturi/sim/haptic.h"

#include <algorithm>
#include <cmath>
#include <utility>

#include <glm/geometric.hpp>

namespace bisturi::sim {
namespace {

/// The contact patch around a surface point: its area-weighted outward normal and its vertices
/// with the weights the reaction is shared by.
glm::dvec3 contact_patch(const SoftBody& body, const SurfaceBvh& bvh, const SurfacePoint& at,
                         double probe_radius_m, std::vector<std::uint32_t>& tris,
                         std::vector<std::uint32_t>& vertices, std::vector<double>& weights) {
  const auto& x = body.positions();
  const auto& idx = body.triangles().indices;
  const std::uint32_t* hit = &idx[3 * std::size_t{at.triangle}];
  // The probe's footprint and about a triangle round it, so the patch holds vertices on a coarse
  // surface too: the facets within the probe radius and the touched triangle's longest edge, but
  // at most two of its shortest. A sliver's length says nothing of where the surface bends (its
  // width does); by its length a sliver the length of a vessel would take in the whole tube.
  // Their corners share the reaction by distance over the probe radius and the longest edge,
  // which reaches the touched triangle's own corners however long it is.
  double longest = 0.0, shortest = HUGE_VAL;
  for (int k = 0; k < 3; ++k) {
    const double edge = glm::length(x[hit[(k + 1) % 3]] - x[hit[k]]);
    longest = std::max(longest, edge);
    shortest = std::min(shortest, edge);
  }
  const double radius = probe_radius_m + std::min(longest, 2.0 * shortest);
  const double reach = probe_radius_m + longest;
  bvh.triangles_near(body, at.point_m, radius, tris);
  glm::dvec3 normal(0.0);
  vertices.clear();
  for (std::uint32_t t : tris) {
    const std::uint32_t* c = &idx[3 * std::size_t{t}];
    normal += glm::cross(x[c[1]] - x[c[0]], x[c[2]] - x[c[0]]);
    vertices.insert(vertices.end(), {c[0], c[1], c[2]});
  }
  normal *= body.orientation();
  const double len = glm::length(normal);
  normal = len > 0.0 && glm::dot(normal, at.normal) > 0.0 ? normal / len : at.normal;
  std::sort(vertices.begin(), vertices.end());
  vertices.erase(std::unique(vertices.begin(), vertices.end()), vertices.end());
  weights.assign(vertices.size(), 0.0);
  double total = 0.0;
  for (std::size_t i = 0; i < vertices.size(); ++i) {
    const double d = glm::length(x[vertices[i]] - at.point_m) / reach;
    if (d < 1.0 && body.mass(VertexId(vertices[i])) > 0.0) weights[i] = (1.0 - d) * (1.0 - d);
    total += weights[i];
  }
  if (!(total > 0.0)) {  // degenerate patch: the touched triangle's corners by barycentrics
    vertices.assign(hit, hit + 3);
    weights.assign({at.barycentric.x, at.barycentric.y, at.barycentric.z});
    total = 1.0;
  }
  for (double& w : weights)
    w /= total;
  return normal;
}

/// Whether the segment's box meets the box [lo, hi] grown by pad (a cheap test before a sweep).
bool segment_box_overlap(const glm::dvec3& a, const glm::dvec3& b,
                         const std::pair<glm::dvec3, glm::dvec3>& box, double pad) {
  for (int k = 0; k < 3; ++k) {
    if (std::max(a[k], b[k]) < box.first[k] - pad || std::min(a[k], b[k]) > box.second[k] + pad)
      return false;
  }
  return true;
}

/// The first face the path from -> to enters from its front side, over the live bodies; a
/// path leaving a body first (a back face) enters nothing.
SurfacePoint first_entry(const glm::dvec3& from, const glm::dvec3& to,
                         std::span<const TouchTarget> targets, double pad,
                         std::int32_t& entered_body) {
  SurfacePoint best;
  entered_body = -1;
  const glm::dvec3 path = to - from;
  for (std::size_t b = 0; b < targets.size(); ++b) {
    const TouchTarget& t = targets[b];
    if (t.body->frozen() || !t.touchable || !segment_box_overlap(from, to, t.bvh->bounds(), pad))
      continue;
    const SurfacePoint hit = t.bvh->ray(*t.body, from, to);
    if (!hit.found || glm::dot(path, hit.normal) >= 0.0) continue;
    if (!best.found || hit.distance_m < best.distance_m) {
      best = hit;
      entered_body = static_cast<std::int32_t>(b);
    }
  }
  return best;
}

}  // namespace

bool HapticProxy::steady_contact(const SurfacePoint& best, std::int32_t body,
                                 const glm::dvec3& motion) const {
  // The closest facet must face the contact's side: on a small dented tube a facet under the
  // probe tilts well past 60 degrees from the patch's normal, and taking the sweep there (its
  // entry patch tilted the other way) made a resting probe chatter. A facet facing away is the
  // far side of a thin wall: the sweep is taken.
  if (!contact_ || body != contact_body_ || glm::dot(best.normal, contact_normal_) <= 0.0)
    return false;
  // The closest point must stay near last tick's footprint (the proxy's foot on the surface):
  // within the device's slide since, the probe radius and last tick's depth (a deep press on
  // soft tissue has its closest point off to the side of the dent).
  const double r = options_.probe_radius_m;
  const glm::dvec3 footprint = proxy_ - r * contact_normal_;
  const glm::dvec3 slide = motion - glm::dot(motion, contact_normal_) * contact_normal_;
  return glm::length(best.point_m - footprint) <= glm::length(slide) + r + contact_depth_;
}

HapticOutput HapticProxy::update(const glm::dvec3& device, std::span<const TouchTarget> targets,
                                 double dt_s) {
  if (!initialised_) {
    proxy_ = device;
    last_device_ = device;
    initialised_ = true;
  }
  const double r = options_.probe_radius_m;
  // The closest surface point over every live body.
  SurfacePoint best;
  std::int32_t best_body = -1;
  for (std::size_t b = 0; b < targets.size(); ++b) {
    if (targets[b].body->frozen() || !targets[b].touchable) continue;
    const SurfacePoint sp = targets[b].bvh->closest_point(*targets[b].body, device);
    if (sp.found && (!best.found || sp.distance_m < best.distance_m)) {
      best = sp;
      best_body = static_cast<std::int32_t>(b);
    }
  }
  // The sweep: from last tick's proxy (on the free side of every surface) to the device. Paths
  // shorter than a tenth of the probe radius cannot cross what the closest point misses.
  const glm::dvec3 path = device - proxy_;
  if (options_.continuous && glm::length(path) > 0.1 * r &&
      !(best.found && steady_contact(best, best_body, device - last_device_))) {
    std::int32_t entered = -1;
    const SurfacePoint entry = first_entry(proxy_, device, targets, r, entered);
    if (entry.found) {
      best = entry;
      best_body = entered;
    }
  }
  HapticOutput out;
  glm::dvec3 target_proxy = device;
  bool contact = false;
  glm::dvec3 n(0.0);
  if (best.found && glm::dot(device - best.point_m, best.normal) < 2.0 * r) {
    const TouchTarget& t = targets[static_cast<std::size_t>(best_body)];
    n = contact_patch(*t.body, *t.bvh, best, r, near_, patch_, weights_);
    const double signed_distance = glm::dot(device - best.point_m, n);
    if (signed_distance < r) {
      contact = true;
      // On the patch's tangent plane at probe-radius distance, straight above the device: the
      // coupling pulls along the patch normal (facets of the dent tilt; the patch does not).
      target_proxy = device + (r - signed_distance) * n;
      out.depth_m = r - signed_distance;
    }
  }
  if (contact && contact_ && options_.friction > 0.0) {
    // Stick while the tangential pull is inside the cone; else slide to the cone's edge.
    glm::dvec3 slip = target_proxy - proxy_;
    slip -= glm::dot(slip, n) * n;
    const double normal_force = options_.coupling_N_per_m * out.depth_m;
    const double allowed = options_.friction * normal_force / options_.coupling_N_per_m;
    const double len = glm::length(slip);
    if (len <= allowed) {
      target_proxy -= slip;
    } else {
      target_proxy -= slip * (allowed / len);
    }
  }
  proxy_ = target_proxy;
  contact_ = contact;
  contact_body_ = contact ? best_body : -1;
  contact_normal_ = n;
  last_device_ = device;
  contact_depth_ = contact ? out.depth_m : 0.0;

  const glm::dvec3 force = limited(options_.coupling_N_per_m * (proxy_ - device), dt_s);

  reacted_body_ = -1;
  if (contact && options_.apply_reaction) {
    SoftBody& body = *targets[static_cast<std::size_t>(best_body)].body;
    for (std::size_t i = 0; i < patch_.size(); ++i) {
      if (weights_[i] <= 0.0) continue;
      const VertexId v(patch_[i]);
      body.add_force(v, -force * weights_[i]);
      // Stiffness only (no force): the proxy rides on the surface, so the reaction on the patch
      // weakens as the patch gives way; the solve sees that.
      body.add_contact(v, n, 0.0, options_.coupling_N_per_m * weights_[i], probe_);
    }
    reacted_body_ = best_body;
    reaction_normal_ = n;
    patch_height_ = patch_height(body);
  }
  if (reacted_body_ < 0) last_force_ = force;
  out.force_N = force;
  out.proxy_m = proxy_;
  out.contact = contact;
  out.body = contact ? best_body : -1;
  return out;
}

double HapticProxy::patch_height(const SoftBody& body) const {
  double height = 0.0;
  for (std::size_t i = 0; i < patch_.size(); ++i) {
    if (weights_[i] > 0.0)
      height += weights_[i] * glm::dot(body.position(VertexId(patch_[i])), reaction_normal_);
  }
  return height;
}

glm::dvec3 HapticProxy::limited(glm::dvec3 force, double dt_s) const {
  const double mag = glm::length(force);
  if (mag > options_.max_force_N) force *= options_.max_force_N / mag;
  // Ramp: the output never changes by more than the rate limit in one step.
  const glm::dvec3 change = force - last_force_;
  const double max_change = options_.max_force_rate_N_per_s * dt_s;
  const double change_len = glm::length(change);
  if (change_len > max_change) force = last_force_ + change * (max_change / change_len);
  return force;
}

HapticOutput HapticProxy::settle(std::span<const TouchTarget> targets, HapticOutput out,
                                 double dt_s) {
  if (reacted_body_ < 0) return out;
  const SoftBody& body = *targets[static_cast<std::size_t>(reacted_body_)].body;
  reacted_body_ = -1;
  // How far the patch gave way along the normal during the step: the proxy rides on it, and
  // the solve ended with the reaction weakened by the coupling times that (the contact
  // stiffness it was handed). The device gets that end-of-step force, the one the tissue got.
  const double height = patch_height(body);
  const double give = std::isfinite(height) ? height - patch_height_ : 0.0;
  glm::dvec3 force = out.force_N + options_.coupling_N_per_m * give * reaction_normal_;
  // A probe pushes; it never pulls the device into the tissue.
  if (glm::dot(force, reaction_normal_) < 0.0) force = glm::dvec3(0.0);
  force = limited(force, dt_s);
  last_force_ = force;
  proxy_ += give * reaction_normal_;
  out.force_N = force;
  out.proxy_m = proxy_;
  out.depth_m = std::max(0.0, out.depth_m + give);
  return out;
}

}  // namespace bisturi::sim
