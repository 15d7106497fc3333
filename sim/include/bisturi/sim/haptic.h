#pragma once
// Haptic rendering with a god-object proxy. The device point (the probe tip) is coupled to a
// proxy by a virtual spring; the proxy stays on the tissue surface (at probe-radius distance)
// while the device is inside, and follows the device outside. The force sent to the device is
// the coupling force, clamped to max_force_N and rate-limited (ramped, never stepped: its change
// per step is at most max_force_rate_N_per_s * dt). Optional Coulomb friction holds the proxy
// still while the tangential pull is inside the friction cone.
//
// The contact is a patch, not a triangle: the surface within probe_radius + one edge of the
// closest point. Its area-weighted normal is the proxy's normal (a single triangle's normal on a
// dimpled, yielding membrane tilts from step to step and pushes the probe sideways), and the
// reaction (minus the force) is shared by the patch's vertices with weights (1 - d/R)^2, so the
// tissue yields under the probe as a smooth dent. The reaction's stiffness (coupling x weight
// along the normal) goes to the implicit solve with the force (SoftBody::add_contact), which
// keeps the loop between the proxy and the light surface vertices stable. The force sent is the
// coupling's at the end of the step (settle()): the reaction the solve ended with.
//
// Continuous collision: the closest point alone loses a fast tip. At 1 m/s the tip moves 1 mm
// per 1 kHz tick, so it can cross a thin sheet in one tick, or pass a curved surface's
// mid-plane, where the closest point jumps to the far side and the coupling pushes the tip on
// through. With HapticOptions::continuous, each tick sweeps the path from the last proxy to the
// device (a segment query) unless the contact is a steady one, and the first face the path
// enters from its front side is the contact (docs/sim/collision.md).
// Output in newtons, world frame; sim never talks to devices (the runtime passes it on).

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

struct HapticOptions {
  double coupling_N_per_m = 400.0;
  double max_force_N = 3.0;
  double max_force_rate_N_per_s = 300.0;
  double friction = 0.0;  ///< Coulomb coefficient; 0 turns friction off
  double probe_radius_m = 0.001;
  bool apply_reaction = true;
  /// Sweep the tip's path within a tick (continuous collision); off: closest point only.
  /// Off by default until sessions step the volume model: on the spring membrane the sweep's
  /// deep entries made the multirate procedure diverge (docs/sim/collision.md).
  bool continuous = false;
};

struct HapticOutput {
  glm::dvec3 force_N{0.0};
  glm::dvec3 proxy_m{0.0};
  bool contact = false;
  std::int32_t body = -1;  ///< touched body, -1 when none
  double depth_m = 0.0;    ///< how far the device is below the proxy
  /// How far the touched body gives at the contact patch along its normal per newton over a
  /// step like the last (m/N), the probe's own coupling excluded: a volume's compliance
  /// (VolumeBody::probe_compliance), 0 for a membrane (the proxy is held between steps).
  double compliance_m_per_N = 0.0;
  /// The touched patch's velocity along its normal at the end of the step (m/s): a volume's,
  /// which goes on moving between steps; zero for a membrane.
  glm::dvec3 patch_velocity_m_s{0.0};
};

/// A body the proxy can touch: the body and its BVH (already refitted for this step).
struct TouchTarget {
  SoftBody* body;
  const SurfaceBvh* bvh;
  bool touchable = true;  ///< false: the probe passes it (tissue the instrument's jaws hold)
};

class HapticProxy {
 public:
  /// `probe`: this proxy's index among the world's probes, which tags its contacts
  /// (SoftBody::add_contact).
  explicit HapticProxy(const HapticOptions& options = {}, std::int32_t probe = 0)
      : options_(options), probe_(probe) {}
  /// One haptic step of length dt_s with the device at device_m, before the bodies' step: finds
  /// the contact and gives the touched body the reaction. Frozen bodies are not touched.
  HapticOutput update(const glm::dvec3& device_m, std::span<const TouchTarget> targets,
                      double dt_s);
  /// After the bodies' step: the output of update() with the force the coupling has at the end
  /// of the step (the touched patch gave way under it), which is the reaction the tissue got.
  /// Clamped and ramped like update()'s.
  HapticOutput settle(std::span<const TouchTarget> targets, HapticOutput out, double dt_s);
  [[nodiscard]] const HapticOptions& options() const { return options_; }
  void set_options(const HapticOptions& options) { options_ = options; }

 private:
  /// The force clamped to the limit and ramped from the last output.
  [[nodiscard]] glm::dvec3 limited(glm::dvec3 force, double dt_s) const;
  /// The contact patch's weighted height along reaction_normal_ (how far settle() sees it give).
  [[nodiscard]] double patch_height(const SoftBody& body) const;
  /// Whether the closest point `best` on target `body` continues last tick's contact, the
  /// device having moved by `motion` since (then nothing was crossed and the sweep is skipped).
  [[nodiscard]] bool steady_contact(const SurfacePoint& best, std::int32_t body,
                                    const glm::dvec3& motion) const;

  HapticOptions options_;
  std::int32_t probe_ = 0;
  glm::dvec3 proxy_{0.0};
  /// The reaction of update() waiting for settle(): its body (-1: none), the patch normal and
  /// the patch's weighted height along it before the step.
  std::int32_t reacted_body_ = -1;
  glm::dvec3 reaction_normal_{0.0};
  double patch_height_ = 0.0;
  glm::dvec3 last_force_{0.0};
  bool initialised_ = false;
  bool contact_ = false;
  std::int32_t contact_body_ = -1;  ///< last tick's touched body
  glm::dvec3 contact_normal_{0.0};  ///< and its patch normal
  double contact_depth_ = 0.0;      ///< and how deep the device was
  glm::dvec3 last_device_{0.0};
  std::vector<std::uint32_t> near_, patch_;  // scratch, kept from tick to tick
  std::vector<double> weights_;
};

}  // namespace bisturi::sim
