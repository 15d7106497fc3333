#pragma once
// A soft body whose motion comes from a volume: the hexahedral lattice under its closed DLFL
// surface (hex_lattice.h), elastic from the material's modulus (elastic_volume.h), with every
// surface vertex embedded in it. The SoftBody stays what is drawn, touched, grasped and cut;
// each step the loads the world gave its vertices (forces, penalty contacts with their
// stiffness, grasped vertices' targets) go to the lattice's nodes by the embedding weights, the
// volume takes one implicit step, and the vertices' positions and velocities are read back from
// it. Anchored vertices hold the nodes of their cells.
//
// A cut with the blade's sheet (cut()) splits the cells along it finer (cut_refine_factor),
// separates the lattice along it (lattice_cut.h) and embeds
// each lip of the surface on its own side, so the wound opens as far as the tissue's resting
// tension pulls it. A cut without one changes the surface only: the new vertices are embedded
// where their originals are and both lips follow the same cells.

#include <cstdint>
#include <vector>

#include "bisturi/sim/cutting.h"
#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/tissue.h"
#include "bisturi/sim/volume/elastic_volume.h"
#include "bisturi/sim/volume/lattice_cut.h"

namespace bisturi::sim {

struct VolumeOptions {
  /// Cell side (metres): the lattice is uniform at this size, but for the refined box.
  double cell_m = 0.006;
  /// Cells meeting the cube of this half width about refine_centre_m are split into
  /// refine_factor^3 (hex_lattice.h, build_two_level_lattice): resolution where the instrument
  /// works. 1: none.
  std::uint32_t refine_factor = 1;
  glm::dvec3 refine_centre_m{0.0};
  double refine_half_width_m = 0.0;
  /// The refined box follows the first haptic probe: when its contact on this body is more
  /// than half the half width from the box's centre, the lattice is built again about it
  /// (VolumeBody::refocus), and the cells it left are coarse again. Once a cut has parted
  /// the volume the box stays where it is (a lattice built again would have no wound).
  bool refine_follows = false;
  ElasticMaterial material;
  ElasticLaw law = ElasticLaw::Corotational;
  /// Stiffness of the spring pulling a grasped vertex to its target (N/m); 0: 20 E h, what
  /// twenty cells of side h resist with.
  double target_stiffness_N_per_m = 0.0;
  /// The step's solve: relative residual (warm started from the last step's velocity change).
  double cg_tolerance = 1e-3;
  int max_cg = 100;
  /// The tissue's resting tension (Pa; ElasticVolume::set_resting_tension): what opens a
  /// wound. 0: none, a cut stays closed.
  double resting_tension_Pa = 0.0;
  /// How long a cut's walls take to let that tension go (s; ElasticVolume::fade_in_from):
  /// the share still held after t is exp(-t / this). 0: at once.
  double tension_release_s = 0.3;
  /// At a cut through a lattice of one level, the cells the blade's sheet meets (and those next
  /// to them) are split into this^3 first, the nodes taking the lattice's motion where they are,
  /// so the wound opens at the fine cells' resolution: a cut shallower than half a coarse cell
  /// parts the tissue too. 1: the cut parts the cells as they are.
  std::uint32_t cut_refine_factor = 1;
  /// The body's weight is carried by what surrounds it (a scanned organ is at rest in its scan
  /// under its supports): its steps take no gravity.
  bool weight_supported = false;
  /// Sleeping (with IntegratorOptions::sleeping, after its sleep_steps): a body with no load on
  /// it, its supports still and no wound still letting go, whose nodes all stayed slower than
  /// this for sleep_steps steps, stops (its velocities zeroed) and skips its steps until a load,
  /// a moving support, a cut or a rebuild wakes it.
  double sleep_speed_m_s = 1e-4;
};

/// Per vertex slot of `body` just cut by `cut`, the side of `lattice`'s cut sheets each lip
/// belongs to (+1 or -1: where the surface's faces around it lie), 0 for every other vertex
/// (embed_point_on_side takes where it lies then).
std::vector<std::int8_t> lip_sides(const SoftBody& body, const CutResult& cut,
                                   const HexLattice& lattice);

class VolumeBody {
 public:
  /// The lattice under `body`'s surface at its rest positions, its vertices embedded and its
  /// anchored vertices' cells held. Throws SimInputError when the body has no closed surface or
  /// a vertex cannot be embedded.
  VolumeBody(const SoftBody& body, const VolumeOptions& options);

  /// One step of options.dt_s (gravity and the guard's speed limit from `options`): the body's
  /// loads in, its vertices' state out, its loads cleared. A non-finite state or a node faster
  /// than the limit rolls the step back and retries it in 2, 4, 8 substeps, then freezes the
  /// body (events as the spring integrator reports them). A frozen body does not move.
  StepStats step(SoftBody& body, const IntegratorOptions& options, std::vector<SimEvent>& events,
                 std::uint32_t body_index, std::uint64_t step);
  /// After a topology change: embeds the vertices the body gained (at their rest positions).
  void sync_topology(const SoftBody& body);
  /// Whether the body is asleep (VolumeOptions::sleep_speed_m_s): its steps skipped.
  [[nodiscard]] bool asleep() const { return asleep_; }
  /// Steps taken so far, and of those, how many it slept through.
  [[nodiscard]] std::uint64_t steps() const { return steps_; }
  [[nodiscard]] std::uint64_t asleep_steps() const { return asleep_steps_; }
  /// Wakes it (and starts its count of quiet steps again).
  void wake() {
    asleep_ = false;
    quiet_steps_ = 0;
  }
  /// After `cut` was made on the body's surface by a blade whose sheet (where it entered the
  /// surface and where its tip was, per sample, in the world now) is `sheet`: separates the
  /// lattice along the sheet and embeds every vertex again, each lip on its own side. The
  /// nodes keep their motion; a node's copies share its load from the surroundings (with
  /// cut_refine_factor, the cells along the sheet are split first). Returns the count of
  /// lattice faces separated: 0 when the sheet parts no cells (then only the new vertices are
  /// embedded, as sync_topology does). Allocates: between steps, on the tissue's thread.
  std::size_t cut(SoftBody& body, const CutResult& cut, const BladeSheet& sheet);
  /// Lattice faces separated by cuts so far.
  [[nodiscard]] std::size_t separated_faces() const { return separated_faces_; }
  /// Counts the lattice's rebuilds (a refocus or a cut that separated cells): what was
  /// embedded in the lattice must be embedded again when it moves.
  [[nodiscard]] std::uint64_t lattice_version() const { return lattice_version_; }

  /// Builds the lattice again with its refined box about `centre_m` (a two-level lattice
  /// only): the new nodes take the old lattice's motion where they are (positions and
  /// velocities interpolated in the old cells), the surface is embedded again and the anchored
  /// cells held again. Allocates and takes a few milliseconds: between steps, on the tissue's
  /// thread.
  void refocus(SoftBody& body, const glm::dvec3& centre_m);
  /// Whether a contact at `point_m` is far enough from the refined box's centre for a
  /// following box to move (refine_follows).
  [[nodiscard]] bool should_follow(const glm::dvec3& point_m) const;
  [[nodiscard]] const VolumeOptions& options() const { return options_; }
  /// How many times the box moved, and the longest rebuild (ms).
  [[nodiscard]] std::uint64_t refocus_count() const { return refocus_count_; }
  [[nodiscard]] double longest_refocus_ms() const { return longest_refocus_ms_; }

  [[nodiscard]] const ElasticVolume& volume() const { return volume_; }
  /// The anchored part (its held cells) moves at `velocity` from the next step on, the rest
  /// following through the elements (ElasticVolume::set_held_velocity): breathing.
  void move_support(const glm::dvec3& velocity_m_s) {
    if (velocity_m_s != glm::dvec3(0.0)) wake();
    volume_.set_held_velocity(velocity_m_s);
  }
  /// How far the anchored part is from where it was built (m).
  [[nodiscard]] glm::dvec3 support_offset() const { return volume_.held_offset(); }
  /// Embedded vertex slots (alive vertices of the body's mesh).
  [[nodiscard]] std::size_t embedded_vertices() const;
  /// Vertex v's cell and weights in the lattice (null when it is not embedded).
  [[nodiscard]] const EmbeddedPoint* embedding(VertexId v) const {
    return v.idx < embedded_.size() && embedded_[v.idx] ? &embedding_[v.idx] : nullptr;
  }
  /// The last step's compliance under haptic probe `probe`'s contact patch along its normal
  /// (ElasticVolume::step_compliance; m/N): 0 when that probe did not press on this body in
  /// the step, or the step was rolled back.
  [[nodiscard]] double probe_compliance(std::size_t probe) const {
    return probe < probe_compliance_.size() ? probe_compliance_[probe] : 0.0;
  }
  /// Probe `probe`'s patch's velocity along its normal after the last step (m/s; the patch's
  /// points weighted as for the compliance): zero when probe_compliance is.
  [[nodiscard]] glm::dvec3 probe_patch_velocity(std::size_t probe) const {
    return probe < probe_speed_.size() ? probe_speed_[probe] * probe_normal_[probe]
                                       : glm::dvec3(0.0);
  }

 private:
  /// The volume built again from `next_lattice` (the same surface), its nodes taking the
  /// current lattice's motion where they are, every vertex embedded again.
  void rebuild(SoftBody& body, ElasticVolume next);
  /// The first half of rebuild: `next` takes the current lattice's motion and replaces it; the
  /// vertices stay embedded in the old one until embed_again.
  void take_motion(ElasticVolume next);
  /// The second half (and a cut's last step): every vertex embedded again on its side of the
  /// wounds (lip_side_), the anchored ones held, the surface written.
  void embed_again(SoftBody& body);
  /// A later cut's split: the lattice built again with the cells along every cut so far split
  /// (cut_boxes_), separated along the earlier cuts' sheets again, each node taking the current
  /// lattice's motion on its own side of the wounds and what it had still to let go of (the
  /// fading load); the vertices stay embedded in the old one (as take_motion).
  void split_again(const SoftBody& body);
  /// Embeds the alive vertex slots not embedded yet (at their rest positions).
  void embed_slots(const SoftBody& body);
  /// Holds the nodes of the cells holding an anchored vertex.
  void hold_anchored(const SoftBody& body);
  /// The body's loads as point loads on the lattice (into loads_).
  void gather_loads(const SoftBody& body);
  void write_surface(SoftBody& body) const;
  /// After an accepted step: counts it quiet or not, and puts the body to sleep after enough.
  void count_quiet_step(SoftBody& body, const IntegratorOptions& options);
  /// Probe p's compliance under its patch in the step just taken (dt_s long), as a spring in
  /// series with its coupling (probe_compliance()).
  double probe_step_compliance(std::size_t p, double dt_s);
  /// Probe p's patch's speed along its normal now (probe_patch_speed()).
  [[nodiscard]] double probe_step_speed(std::size_t p) const;

  ElasticVolume volume_;
  VolumeOptions options_;
  double target_stiffness_N_per_m_ = 0.0;
  std::vector<EmbeddedPoint> embedding_;  ///< per vertex slot
  std::vector<std::uint8_t> embedded_;    ///< per vertex slot
  /// Per vertex slot: the side of its cut a lip is embedded on (+1 or -1; 0 for every other
  /// vertex, embedded by where it lies). A lip lies on its sheet at rest, where its position
  /// cannot tell the sides apart: every later cut embeds it again on the side it was given.
  std::vector<std::int8_t> lip_side_;
  /// The cells every cut split (cut_refine_factor), and the sheets (rest frame) of the cuts that
  /// parted the volume, in order: a later cut's split builds the lattice again from them.
  std::vector<TwoLevelOptions::Box> cut_boxes_;
  std::vector<BladeSheet> cut_sheets_;
  /// The inside shares those splits' lattices share, taken at construction: the cut's step
  /// does not sample the whole solid again.
  FineShares cut_shares_;
  std::vector<PointLoad> loads_;  // scratch
  /// Per haptic probe: its contact's loads in this step (their stiffness only) and normal.
  std::vector<std::vector<PointLoad>> probe_loads_;
  std::vector<glm::dvec3> probe_normal_;
  std::vector<double> probe_compliance_;
  std::vector<double> probe_speed_;
  std::vector<std::uint8_t> loaded_;  // scratch: per vertex slot
  std::vector<glm::dvec3> saved_x_, saved_v_;
  bool asleep_ = false;
  int quiet_steps_ = 0;
  std::uint64_t steps_ = 0, asleep_steps_ = 0;
  std::size_t separated_faces_ = 0;
  std::uint64_t lattice_version_ = 0;
  std::uint64_t refocus_count_ = 0;
  double longest_refocus_ms_ = 0.0;
};

}  // namespace bisturi::sim
