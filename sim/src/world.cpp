#include "bisturi/sim/world.h"

#include <algorithm>
#include <limits>
#include <stdexcept>
#include <string>

#include <glm/geometric.hpp>
#include <glm/vector_relational.hpp>

namespace bisturi::sim {

SimWorld::SimWorld(const WorldOptions& options)
    : options_(options), device_(std::make_unique<CollisionDevice>(options.embree_threads)) {}

void SimWorld::ensure_probes(std::size_t count) {
  while (proxies_.size() < count)
    proxies_.emplace_back(options_.haptic, static_cast<std::int32_t>(proxies_.size()));
  if (probe_states_.size() < count) probe_states_.resize(count);
  if (targets_.size() < count) targets_.resize(count);
}

void SimWorld::set_probe(std::size_t probe, ProbeState state) {
  ensure_probes(probe + 1);
  probe_states_[probe] = state;
}

std::uint32_t SimWorld::add_body(SoftBody body) {
  bodies_.push_back(std::move(body));
  volumes_.emplace_back();
  bvhs_.emplace_back(*device_, bodies_.back());
  bvhs_.back().set_rebuild_limits(options_.bvh_rebuild);
  stats_.emplace_back();
  integrator_.prepare(bodies_.back(), options_.integrator);
  return static_cast<std::uint32_t>(bodies_.size() - 1);
}

void SimWorld::prepare() {
  for (std::uint32_t i = 0; i < bodies_.size(); ++i)
    prepare_body(i);
}

bool SimWorld::some_volume_asleep() const {
  return std::any_of(volumes_.begin(), volumes_.end(),
                     [](const std::unique_ptr<VolumeBody>& v) { return v && v->asleep(); });
}

void SimWorld::set_volume(std::uint32_t i, const VolumeOptions& options) {
  volumes_.at(i) = std::make_unique<VolumeBody>(bodies_[i], options);
}

void SimWorld::move_support(std::uint32_t i, const glm::dvec3& velocity_m_s) {
  if (!volumes_.at(i))
    throw std::invalid_argument("SimWorld::move_support: body " + std::to_string(i) +
                                " is a surface model (its anchors never move)");
  volumes_[i]->move_support(velocity_m_s);
}

void SimWorld::prepare_body(std::uint32_t i) {
  if (volumes_[i])
    volumes_[i]->sync_topology(bodies_[i]);
  else
    integrator_.prepare(bodies_[i], options_.integrator);
  bvhs_[i].update(bodies_[i]);  // a topology change (a cut) updates the patches now
  if (!options_.contact.enabled) return;
  // The user-geometry copies rtcCollide works on, built by a query whose result is not used.
  for (std::uint32_t j = 0; j < bodies_.size(); ++j) {
    if (j == i) continue;
    (void)bvhs_[i].overlapping_triangles(bodies_[i], bvhs_[j], bodies_[j],
                                         options_.contact.margin_m);
  }
}

HapticOutput SimWorld::step(const glm::dvec3& device_m) {
  HapticOutput out;
  step(std::span<const glm::dvec3>(&device_m, 1), std::span<HapticOutput>(&out, 1));
  return out;
}

void SimWorld::step(std::span<const glm::dvec3> devices_m, std::span<HapticOutput> out) {
  ensure_probes(devices_m.size());
  for (std::size_t p = 0; p < devices_m.size(); ++p) {
    std::vector<TouchTarget>& targets = targets_[p];
    targets.clear();
    for (std::size_t i = 0; i < bodies_.size(); ++i) {
      targets.push_back(
          {&bodies_[i], &bvhs_[i], static_cast<std::int32_t>(i) != probe_states_[p].held_body});
    }
    HapticOptions haptic = options_.haptic;
    haptic.apply_reaction = haptic.apply_reaction && probe_states_[p].pushes;
    proxies_[p].set_options(haptic);
    out[p] = proxies_[p].update(devices_m[p], targets, options_.integrator.dt_s);
  }
  if (options_.contact.enabled && bodies_.size() > 1) tissue_contacts();
  for (std::uint32_t i = 0; i < bodies_.size(); ++i) {
    stats_[i] = volumes_[i] ? volumes_[i]->step(bodies_[i], options_.integrator, events_, i, steps_)
                            : integrator_.step(bodies_[i], options_.integrator, events_, i, steps_);
    // A body asleep entirely did not move: its BVH still fits.
    const StepStats& s = stats_[i];
    bvhs_[i].set_refit_tolerance(options_.bvh_refit_tolerance_m);
    if (!(s.free_vertices > 0 && s.awake_vertices == 0)) bvhs_[i].update(bodies_[i]);
  }
  for (std::size_t p = 0; p < devices_m.size(); ++p) {
    out[p] = proxies_[p].settle(targets_[p], out[p], options_.integrator.dt_s);
    const VolumeBody* touched =
        out[p].body >= 0 ? volumes_[std::size_t(out[p].body)].get() : nullptr;
    out[p].compliance_m_per_N = touched ? touched->probe_compliance(p) : 0.0;
    out[p].patch_velocity_m_s = touched ? touched->probe_patch_velocity(p) : glm::dvec3(0.0);
  }
  // A refined box that follows the first probe moves to its contact (the next step on): the
  // surface under the proxy, a probe radius below it towards the tip.
  if (!out.empty() && out[0].contact && out[0].body >= 0 && out[0].depth_m > 0.0) {
    const auto b = static_cast<std::uint32_t>(out[0].body);
    const glm::dvec3 inward = glm::normalize(devices_m[0] - out[0].proxy_m);
    const glm::dvec3 contact = out[0].proxy_m + options_.haptic.probe_radius_m * inward;
    if (volumes_[b] && volumes_[b]->should_follow(contact)) {
      volumes_[b]->refocus(bodies_[b], contact);
      bvhs_[b].update(bodies_[b]);
    }
  }
  ++steps_;
}

void SimWorld::tissue_contacts() {
  last_contacts_ = 0;
  const double margin = options_.contact.margin_m;
  for (std::size_t a = 0; a < bodies_.size(); ++a) {
    for (std::size_t b = a + 1; b < bodies_.size(); ++b) {
      SoftBody& A = bodies_[a];
      SoftBody& B = bodies_[b];
      if (A.frozen() || B.frozen()) continue;
      // Broad phase: bodies whose boxes, grown by the margin, are apart cannot touch (the
      // user-geometry copies rtcCollide needs cost a pass over every triangle of both).
      const auto [lo_a, hi_a] = bvhs_[a].bounds();
      const auto [lo_b, hi_b] = bvhs_[b].bounds();
      if (glm::any(glm::greaterThan(lo_a - margin, hi_b)) ||
          glm::any(glm::greaterThan(lo_b - margin, hi_a)))
        continue;
      const auto pairs = bvhs_[a].overlapping_triangles(A, bvhs_[b], B, margin);
      if (pairs.empty()) continue;
      // Both ways: A's vertices out of B, B's out of A (each side's push is the other's
      // reaction, spread over its own vertices).
      last_contacts_ +=
          push_out(A, PairSide::First, B, bvhs_[b], pairs, options_.contact, contact_scratch_);
      last_contacts_ +=
          push_out(B, PairSide::Second, A, bvhs_[a], pairs, options_.contact, contact_scratch_);
    }
  }
}

CutResult SimWorld::cut(std::uint32_t i, std::span<const glm::dvec3> points_m,
                        const CutOptions& options, std::span<const glm::dvec3> blade_tips_m) {
  CutOptions with_walls = options;
  if (volumes_[i]) with_walls.blade_tips_m = blade_tips_m;  // a solid's wound has walls
  CutResult r = cut_surface(bodies_[i], points_m, with_walls);
  if (volumes_[i] && blade_tips_m.size() == points_m.size()) {
    const BladeSheet sheet{{points_m.begin(), points_m.end()},
                           {blade_tips_m.begin(), blade_tips_m.end()}};
    volumes_[i]->cut(bodies_[i], r, sheet);
  }
  prepare_body(i);  // the solver structure and BVH copies now, not in the next step
  return r;
}

std::size_t SimWorld::separated_faces(std::uint32_t i) const {
  return volumes_.at(i) ? volumes_[i]->separated_faces() : 0;
}

std::vector<SimEvent> SimWorld::take_events() {
  std::vector<SimEvent> out;
  out.swap(events_);
  return out;
}

}  // namespace bisturi::sim
