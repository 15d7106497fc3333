#pragma once
// A soft solid: a DLFL surface with a mass-spring model on it (springs.h), its state in SI units
// and the implicit integrator that advances it (integrator.h).
//
// Per-vertex state lives in property arrays attached to the solid's Dlfl (names "sim.*"), so it
// follows vertex creation and compaction like every other attribute. Springs, masses and the
// surface triangles are derived data: they are rebuilt when the Dlfl's topology_version() moves
// (after a cut), and only then.

#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"
#include "bisturi/sim/material.h"
#include "bisturi/sim/springs.h"

namespace bisturi::sim {

class SoftBody {
 public:
  /// Takes the solid (positions in scene millimetres, converted once here) and its material.
  /// The current shape is the rest shape. Throws SimInputError for a bad material or a solid
  /// with no faces.
  SoftBody(Dlfl mesh, const Material& material);

  SoftBody(SoftBody&&) noexcept = default;
  SoftBody& operator=(SoftBody&&) noexcept = default;
  /// A deep copy (mesh, state, derived data) with its own lineage and generation: a solver may
  /// advance it apart from the original (the multirate far field does).
  SoftBody(const SoftBody& other);
  SoftBody& operator=(const SoftBody&) = delete;

  [[nodiscard]] const Dlfl& mesh() const { return mesh_; }
  /// For topological edits (cutting); call refresh_topology() after them.
  Dlfl& mesh_for_edit() {
    ++state_edits_;
    return mesh_;
  }
  [[nodiscard]] const Material& material() const { return material_; }

  // ---- State (metres, m/s, kg), indexed by vertex handle ----
  [[nodiscard]] const glm::dvec3& position(VertexId v) const { return (*x_)[v]; }
  [[nodiscard]] const glm::dvec3& velocity(VertexId v) const { return (*v_)[v]; }
  [[nodiscard]] const glm::dvec3& rest_position(VertexId v) const { return (*rest_)[v]; }
  [[nodiscard]] double mass(VertexId v) const { return mass_[v.idx]; }
  void set_position(VertexId v, const glm::dvec3& p_m) {
    ++state_edits_;
    (*x_)[v] = p_m;
  }
  void set_velocity(VertexId v, const glm::dvec3& v_m_s) {
    ++state_edits_;
    (*v_)[v] = v_m_s;
  }
  void set_rest_position(VertexId v, const glm::dvec3& p_m) { (*rest_)[v] = p_m; }
  /// Grows the per-vertex arrays to the Dlfl's vertex capacity (vertices created by an edit).
  void ensure_capacity();
  /// Dense views over vertex slots (dead slots have zero mass and are never moved).
  /// The non-const views count as edits (state_edits()): read through a const body.
  std::vector<glm::dvec3>& positions() {
    ++state_edits_;
    return x_->raw();
  }
  [[nodiscard]] const std::vector<glm::dvec3>& positions() const { return x_->raw(); }
  std::vector<glm::dvec3>& velocities() {
    ++state_edits_;
    return v_->raw();
  }
  [[nodiscard]] const std::vector<glm::dvec3>& velocities() const { return v_->raw(); }
  /// Counts the calls that can change positions or velocities (the non-const views, the
  /// setters, mesh_for_edit, ensure_capacity): data computed from the state stays valid while
  /// it does not move. A non-const view kept across calls and written later is not counted.
  [[nodiscard]] std::uint64_t state_edits() const { return state_edits_; }
  [[nodiscard]] const std::vector<double>& masses() const { return mass_; }

  /// Anchored vertices never move (their velocity is zero).
  void set_anchored(VertexId v, bool anchored);
  [[nodiscard]] bool anchored(VertexId v) const { return (*anchored_)[v] != 0; }
  /// Kinematic vertices follow a prescribed position each step (grasped tissue); they act as
  /// moving anchors. Cleared by release_kinematic().
  void set_kinematic_target(VertexId v, const glm::dvec3& target_m);
  void release_kinematic(VertexId v);
  [[nodiscard]] bool kinematic(VertexId v) const { return kinematic_[v.idx] != 0; }
  [[nodiscard]] const glm::dvec3& kinematic_target(VertexId v) const { return target_[v.idx]; }
  /// Vertices with a kinematic target now.
  [[nodiscard]] std::size_t kinematic_count() const { return kinematic_count_; }
  /// Counts the calls that change which vertices are constrained (an anchor set or cleared, a
  /// kinematic target set on a free vertex or released): with derived_generation() (masses),
  /// data computed from the constraints stays valid while it does not move.
  [[nodiscard]] std::uint64_t constraint_edits() const { return constraint_edits_; }

  /// External force (N) on v for the next step only (contacts, haptic reaction).
  void add_force(VertexId v, const glm::dvec3& force_N) {
    force_[v.idx] += force_N;
    loaded_.push_back(v.idx);
  }
  [[nodiscard]] const std::vector<glm::dvec3>& external_forces() const { return force_; }
  /// A penalty contact on v for the next step only: the force stiffness * depth along the unit
  /// normal, with its stiffness (stiffness * n n^T) handed to the implicit solve, so a stiff
  /// penalty on a light vertex stays stable (an explicit one of the same size would not).
  /// `probe`: the haptic probe whose proxy this contact couples to (-1: none), so that a volume
  /// can tell the probe its compliance under the patch (VolumeBody::probe_compliance).
  void add_contact(VertexId v, const glm::dvec3& normal, double depth_m, double stiffness_N_per_m,
                   std::int32_t probe = -1);
  struct ContactTerm {
    std::uint32_t vertex = 0;
    glm::dvec3 normal{0.0};
    double stiffness_N_per_m = 0.0;
    std::int32_t probe = -1;
  };
  [[nodiscard]] const std::vector<ContactTerm>& contacts() const { return contacts_; }
  /// The vertices given a force or a contact since the last clear_forces(), in call order (a
  /// vertex may be listed more than once): the only ones with a nonzero external force.
  [[nodiscard]] const std::vector<std::uint32_t>& loaded_vertices() const { return loaded_; }
  /// Clears the external forces and contacts.
  void clear_forces();
  /// Replaces this body's external forces and contacts with those given to `other` since its
  /// last clear_forces() (`other` is a copy of this body: the same vertices).
  void set_loads_from(const SoftBody& other);

  // ---- Derived data ----
  [[nodiscard]] const std::vector<Spring>& springs() const { return springs_; }
  [[nodiscard]] const SurfaceTriangles& triangles() const { return triangles_; }
  /// True when the solid has no labelled face (a closed organ): it gets the volume term.
  [[nodiscard]] bool closed() const { return closed_; }
  [[nodiscard]] double rest_volume_m3() const { return rest_volume_m3_; }
  /// +1 when the faces wind counter-clockwise seen from outside (positive enclosed volume),
  /// -1 when they wind inward (marching cubes' convention, for one): triangle normals times
  /// orientation() point out of the tissue.
  [[nodiscard]] double orientation() const { return orientation_; }
  /// Enclosed volume at the current positions (positive for either winding).
  [[nodiscard]] double volume_m3() const;
  /// Rebuilds springs, masses and triangles when mesh().topology_version() moved; returns true
  /// when it did. New vertices must already carry positions (cutting copies them).
  bool refresh_topology();
  /// refresh_topology() after an edit that changed only the faces around `touched` (a cut's
  /// path vertices and their copies): springs and masses are updated in the faces around them
  /// (the rest is kept), triangles are rebuilt. Gives the springs and (to rounding) the masses
  /// of a full rebuild.
  bool refresh_topology_local(std::span<const VertexId> touched);
  /// What the last refresh changed, for data derived from the springs: when it was a local one,
  /// the generation it started from and the vertices whose springs may differ (the region and
  /// the other ends of its springs, before and after; sorted); after a full refresh
  /// from_generation is 0.
  struct SpringChange {
    std::uint64_t from_generation = 0;
    std::vector<std::uint32_t> vertices;
  };
  [[nodiscard]] const SpringChange& last_spring_change() const { return spring_change_; }
  [[nodiscard]] std::uint64_t topology_version() const { return topology_version_; }
  /// Unique over every body of the process and every rebuild of the derived data: a cache key
  /// for data derived from springs and masses (the integrator's solver structure).
  [[nodiscard]] std::uint64_t derived_generation() const { return derived_generation_; }
  /// Unique over every body of the process and kept across topology changes: data derived for
  /// an older generation of the same body can be recycled (its memory is already resident).
  [[nodiscard]] std::uint64_t lineage() const { return lineage_; }

  // ---- Energies (J) for the divergence guard and the tests ----
  [[nodiscard]] double kinetic_energy() const;
  /// Springs + volume term.
  [[nodiscard]] double elastic_energy() const;
  /// Kinetic + elastic + gravitational (relative to z = 0) for gravity g.
  [[nodiscard]] double total_energy(const glm::dvec3& gravity) const;

  // ---- Divergence guard ----
  [[nodiscard]] bool frozen() const { return frozen_; }
  void freeze();
  void unfreeze() { frozen_ = false; }

  /// Writes the positions into the Dlfl in scene millimetres (for renderers and exports).
  void write_positions_to_scene();
  /// FNV-1a hash of the bytes of positions and velocities: equal hashes mean identical states.
  [[nodiscard]] std::uint64_t state_hash() const;

  // Integrator scratch (warm start of the linear solve), kept per body.
  std::vector<glm::dvec3>& warm_start() { return warm_; }

 private:
  void resize_arrays();
  void rebuild_masses();
  /// The version and generation after springs and masses, and when `surface` is set the
  /// triangles and the closed flag (from scratch).
  void finish_refresh(bool surface);
  [[nodiscard]] bool any_bounding_face() const;

  Dlfl mesh_;
  Material material_;
  PropertyArray<VertexTag, glm::dvec3>* x_ = nullptr;
  PropertyArray<VertexTag, glm::dvec3>* v_ = nullptr;
  PropertyArray<VertexTag, glm::dvec3>* rest_ = nullptr;
  PropertyArray<VertexTag, std::uint8_t>* anchored_ = nullptr;
  std::vector<double> mass_;
  std::vector<std::uint8_t> kinematic_;
  std::size_t kinematic_count_ = 0;
  std::uint64_t constraint_edits_ = 0;
  std::vector<std::uint32_t> loaded_;  ///< see loaded_vertices()
  std::vector<glm::dvec3> target_;
  std::vector<glm::dvec3> force_;
  std::vector<glm::dvec3> warm_;
  std::vector<ContactTerm> contacts_;
  std::vector<Spring> springs_;
  SurfaceTriangles triangles_;
  SpringChange spring_change_;
  SurfaceTriangles spare_triangles_;  ///< the triangulation before last, as storage
  bool closed_ = false;
  double rest_volume_m3_ = 0.0;
  double orientation_ = 1.0;
  std::uint64_t topology_version_ = 0;
  std::uint64_t derived_generation_ = 0;
  std::uint64_t lineage_ = 0;
  std::uint64_t state_edits_ = 0;
  bool frozen_ = false;
};

}  // namespace bisturi::sim
