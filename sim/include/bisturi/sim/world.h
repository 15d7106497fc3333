#pragma once
// A simulation world: soft bodies with their BVHs, one haptic proxy per instrument (a hand),
// tissue-tissue contact and the integrator, advanced by one full haptic-rate step at a time:
//   each proxy's force (on the current surface, reaction onto the tissue) -> tissue-tissue
//   contact forces -> implicit step of every body (with the divergence guard) -> BVH refit.
// Two hands act on the same bodies in the same step, so what one pulls the other feels.
// A body is a spring membrane stepped by the ImplicitIntegrator unless it was given a volume
// (set_volume), which then steps it.
// Single-threaded and deterministic. Divergence events are collected for the runtime to report.

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/haptic.h"
#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/tissue_contact.h"
#include "bisturi/sim/volume/volume_body.h"

namespace bisturi::sim {

struct WorldOptions {
  IntegratorOptions integrator;
  HapticOptions haptic;
  ContactOptions contact;
  unsigned embree_threads = 1;
  PatchRebuildLimits bvh_rebuild;  ///< when a cut rebuilds a BVH patch instead of keeping it
  /// A BVH patch is refitted once its vertices may have moved this far since its last refit
  /// (SurfaceBvh::set_refit_tolerance; queries stay exact). 0.1 mm: a tenth of the 20k organ's
  /// edge, so a query visits few more triangles, while patches away from the instrument, which
  /// move microns per step, are refitted every few hundred steps instead of every step.
  double bvh_refit_tolerance_m = 1e-4;
};

class SimWorld {
 public:
  explicit SimWorld(const WorldOptions& options = {});

  /// Adds a body (and builds its BVH and solver structure); returns its index.
  std::uint32_t add_body(SoftBody body);
  /// Builds everything the first step would build lazily (solver structures for the current
  /// anchors, scratch, BVH refit state, the tissue-contact BVHs), so that the first step costs
  /// what later ones do. Call after the bodies are set up (anchors included); cut() does it for
  /// the body it cut. Optional: without it the first step does the same work.
  void prepare();
  /// prepare() for body i alone: after its topology or anchors changed through body(i) (cut()
  /// calls it; the benchmarks time it apart from the cut itself).
  void prepare_body(std::uint32_t i);
  [[nodiscard]] std::size_t body_count() const { return bodies_.size(); }
  SoftBody& body(std::uint32_t i) { return bodies_[i]; }
  [[nodiscard]] const SoftBody& body(std::uint32_t i) const { return bodies_[i]; }
  /// Gives body i a volume (volume_body.h): from now on its steps are the volume's, not the
  /// spring integrator's. Throws SimInputError when the volume cannot be built.
  void set_volume(std::uint32_t i, const VolumeOptions& options);
  /// Body i's volume, or null when it is a surface model.
  [[nodiscard]] const VolumeBody* volume(std::uint32_t i) const { return volumes_[i].get(); }
  /// Whether some body's volume slept through the last step (VolumeBody::asleep).
  [[nodiscard]] bool some_volume_asleep() const;
  /// Body i's anchored part moves at `velocity` from the next step on (VolumeBody::move_support;
  /// a volume only: throws std::invalid_argument for a surface model).
  void move_support(std::uint32_t i, const glm::dvec3& velocity_m_s);
  [[nodiscard]] const SurfaceBvh& bvh(std::uint32_t i) const { return bvhs_[i]; }

  /// One full step with the device (probe tip) at device_m; returns the force for the device.
  HapticOutput step(const glm::dvec3& device_m);
  /// One full step with probe i's tip at devices_m[i]; out[i] gets its force (out is as long).
  void step(std::span<const glm::dvec3> devices_m, std::span<HapticOutput> out);
  /// What a probe may do in a step. held_body: the body its instrument holds (-1: none), which
  /// it does not touch, since the held vertices follow it and a contact would only flicker.
  /// pushes: whether its contact pushes the tissue (not while its blade parts it; the hand
  /// still feels it).
  struct ProbeState {
    std::int32_t held_body = -1;
    bool pushes = true;
  };
  void set_probe(std::size_t probe, ProbeState state);
  /// set_probe(0, ...)'s held body.
  void set_held_body(std::int32_t body) { set_probe(0, {body, probe_state(0).pushes}); }
  [[nodiscard]] ProbeState probe_state(std::size_t probe) const {
    return probe < probe_states_.size() ? probe_states_[probe] : ProbeState{};
  }
  /// Cuts body i along blade contact points and rebuilds its BVH. With the blade's tip at each
  /// point (`blade_tips_m`, as many), a solid's volume is separated along the blade's sheet
  /// too (VolumeBody::cut): the wound opens.
  CutResult cut(std::uint32_t i, std::span<const glm::dvec3> points_m,
                const CutOptions& options = {}, std::span<const glm::dvec3> blade_tips_m = {});
  /// Lattice faces the cuts separated in body i's volume (0 for a surface model).
  [[nodiscard]] std::size_t separated_faces(std::uint32_t i) const;

  /// Vertex contacts made by the last step's tissue-tissue phase (one per vertex pushed out).
  [[nodiscard]] std::size_t last_contacts() const { return last_contacts_; }
  [[nodiscard]] std::uint64_t step_count() const { return steps_; }
  [[nodiscard]] const StepStats& last_stats(std::uint32_t i) const { return stats_[i]; }
  /// Returns and clears the divergence events since the last call.
  std::vector<SimEvent> take_events();
  WorldOptions& options() { return options_; }

 private:
  void tissue_contacts();
  /// Makes probes up to `count` (a new hand's proxy starts untouched).
  void ensure_probes(std::size_t count);

  WorldOptions options_;
  std::unique_ptr<CollisionDevice> device_;  // heap: the world stays movable
  std::vector<SoftBody> bodies_;
  std::vector<std::unique_ptr<VolumeBody>> volumes_;  ///< per body; null: the spring model
  std::vector<SurfaceBvh> bvhs_;
  std::vector<StepStats> stats_;
  ImplicitIntegrator integrator_;
  std::vector<HapticProxy> proxies_;
  std::vector<ProbeState> probe_states_;
  std::vector<std::vector<TouchTarget>> targets_;  ///< per probe, scratch
  std::vector<SimEvent> events_;
  std::uint64_t steps_ = 0;
  std::size_t last_contacts_ = 0;
  ContactScratch contact_scratch_;  ///< tissue_contacts
};

}  // namespace bisturi::sim
