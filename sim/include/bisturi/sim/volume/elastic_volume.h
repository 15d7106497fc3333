#pragma once
// A tissue solid's volume: trilinear hexahedra on a HexLattice, straight from the material's
// Young's modulus and Poisson's ratio, with no spring constant to calibrate: corotated linear
// elasticity (Nesme, Payan and Faure 2005; the rotation of Mueller and Gross 2004, from the
// polar decomposition of each element's deformation gradient at its centre) or compressible
// neo-Hookean, both with selective reduced integration (the volumetric part at the centre: no
// locking near incompressibility), weighted by the cell's inside share.
//
// Two uses: static equilibrium with a rigid spherical probe pressed into the embedded surface
// (`bisturi tissue indent --model volume`; contact by an augmented Lagrangian on the embedded
// surface points, each Newton step solved by block-Jacobi preconditioned CG), and dynamics
// (advance(): one linearised backward Euler step per call, lumped masses from the density,
// Kelvin-Voigt damping from the retardation time, loads on embedded points), which is how a
// session's tissue moves (volume_body.h).

#include <cmath>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "bisturi/sim/tissue.h"
#include "bisturi/sim/volume/embedding.h"
#include "bisturi/sim/volume/hex_lattice.h"

namespace bisturi::sim {

struct PressOptions {
  /// Contact penalty per surface point (N/m); 0: 20 E h (h the finest cell), right for points
  /// about a cell apart; denser points want it smaller in proportion to their share of area.
  double penalty_N_per_m = 0.0;
  int max_newton = 40;
  /// Equilibrium: the residual force at most this share of the probe's force.
  double force_tolerance = 1e-3;
  /// Penetration the augmented Lagrangian may leave (metres).
  double penetration_tolerance_m = 1e-6;
  double cg_tolerance = 1e-3;
  int max_cg = 4000;
};

struct PressResult {
  glm::dvec3 probe_force_N{0.0};  ///< what the tissue pushes the probe with
  std::size_t contacts = 0;       ///< surface points pressing on the probe
  double max_penetration_m = 0.0;
  int newton_iterations = 0;
  long cg_iterations = 0;
  bool converged = false;
};

/// A load on an embedded point for one dynamic step: its force at the current positions and its
/// stiffness (how the force changes per metre the point moves, with the sign of a spring: k n n^T
/// for a penalty contact along n, k I for a spring to a target), which the implicit step takes
/// in as it takes the elements' own.
struct PointLoad {
  EmbeddedPoint point;
  glm::dvec3 force_N{0.0};
  glm::dmat3 stiffness_N_per_m{0.0};
};

struct DynamicOptions {
  double dt_s = 1e-3;
  glm::dvec3 gravity_m_s2{0.0, 0.0, -9.81};
  double cg_tolerance = 1e-4;
  int max_cg = 100;
  /// The step's matrix may warp a cell's stiffness with a rotation this far from the cell's
  /// own (the largest column difference): a Newton matrix a little off costs nothing in
  /// accuracy (the forces use the exact rotation) and saves recomputing R K R^T.
  double warp_tolerance = 0.01;
};

struct DynamicResult {
  int cg_iterations = 0;
  double relative_residual = 0.0;
};

/// How the elements resist: both from E and nu, identical at small strains.
enum class ElasticLaw : std::uint8_t {
  /// Linear elasticity in each element's rotated frame: large rotations, small strains.
  Corotational,
  /// Compressible neo-Hookean (CalculiX's NEO HOOKE, C10 = mu / 2, D1 = 2 / K): finite strains;
  /// a tissue stiffens in compression as it should. Its equilibrium is found with the
  /// corotated linear stiffness as the Newton matrix (exact at small strains), so each step
  /// still solves a symmetric positive definite system.
  NeoHookean,
};

class ElasticVolume {
 public:
  ElasticVolume(HexLattice lattice, const ElasticMaterial& material,
                ElasticLaw law = ElasticLaw::NeoHookean);
  ~ElasticVolume();
  ElasticVolume(ElasticVolume&&) noexcept;
  ElasticVolume& operator=(ElasticVolume&&) noexcept;

  [[nodiscard]] const HexLattice& lattice() const { return lattice_; }
  [[nodiscard]] std::span<const glm::dvec3> positions() const { return x_; }
  /// Holds node i at its rest position (a Dirichlet condition).
  void hold(std::uint32_t node);
  [[nodiscard]] std::size_t held_count() const;
  /// From the next advance() on, the held nodes move together at `velocity` (a support that
  /// moves: breathing displaces an organ through its attachment); zero holds them where they
  /// are. The free nodes follow through the elements.
  void set_held_velocity(const glm::dvec3& velocity_m_s) { held_velocity_ = velocity_m_s; }
  [[nodiscard]] const glm::dvec3& held_velocity() const { return held_velocity_; }
  /// Where the held nodes are, as a displacement from their rest positions (zero without any).
  [[nodiscard]] glm::dvec3 held_offset() const;

  /// Static equilibrium with the rigid sphere (centre, radius) pressing on `points` (embedded
  /// surface points; the same span on every call, whose contact multipliers carry over as warm
  /// starts). The volume starts from its current state.
  PressResult press_sphere(std::span<const EmbeddedPoint> points, const glm::dvec3& centre,
                           double radius, const PressOptions& options = {});

  /// One backward Euler step of options.dt_s, linearised at the current state (one Newton step,
  /// the corotated stiffness as its matrix, Kelvin-Voigt damping tau K):
  ///   (M + (h tau + h^2) K + h^2 L) dv = h (f(x) - tau K v + M g + l) - h^2 (K + L) v,
  ///   v += dv,  x += h v
  /// with L and l the loads' stiffness and force. Held nodes move at the held velocity (at rest
  /// without one): their dv is given, and its product with the matrix leaves the right-hand side.
  DynamicResult advance(std::span<const PointLoad> loads, const DynamicOptions& options);
  /// Right after advance(), whose matrix A it solves with (the loads' stiffness in it): how far
  /// the embedded points of `contact` move along `direction`, weighted by their stiffness along
  /// it, per newton spread over them in the same shares, in a step like that one: h^2 u^T A^-1 u
  /// for the unit load u (m/N). 0 when `contact` has no stiffness along `direction`.
  double step_compliance(std::span<const PointLoad> contact, const glm::dvec3& direction,
                         double dt_s, double cg_tolerance, int max_cg);
  [[nodiscard]] std::span<const glm::dvec3> velocities() const { return v_; }
  /// Each node's lumped mass (kg): the density times its share of its cells' inside volume.
  [[nodiscard]] std::span<const double> masses() const { return mass_; }
  /// Restores a state saved from positions() and velocities() (a rolled-back step).
  void set_state(std::span<const glm::dvec3> positions, std::span<const glm::dvec3> velocities);
  /// The tissue's resting tension (Pa, isotropic; 0: none, the default): each cell pulls its
  /// corners towards its centre with it, turning with the cell, and the pull on the nodes at
  /// rest is taken by a constant load from the surroundings (what holds an organ's tissue
  /// stretched in the body), so the uncut volume stays at rest and a cut that separates cells
  /// (lattice_cut.h) opens.
  void set_resting_tension(double tension_Pa);
  [[nodiscard]] double resting_tension_Pa() const { return tension_Pa_; }
  /// Per node, the surroundings' load (N; empty without a tension).
  [[nodiscard]] std::span<const glm::dvec3> surroundings_load() const { return surroundings_; }
  /// Replaces it (one per node, or empty): after a cut, the copies of a node share its load.
  void set_surroundings_load(std::vector<glm::dvec3> load);
  /// The forces on the nodes in the current state: the elements', the tension's, the
  /// surroundings' and any fading load (no gravity, no step's loads).
  [[nodiscard]] std::vector<glm::dvec3> node_forces();
  /// Adds a load that makes the node forces `before` now and fades over `time_s` (the share
  /// left after t is exp(-t / time_s)): after a cut, the wound's walls let go of what held them
  /// as tissue relaxes, over a second rather than at once. 0: at once.
  void fade_in_from(std::span<const glm::dvec3> before, double time_s);
  /// The fading load now (per node, N; empty without one) and its time constant.
  [[nodiscard]] std::span<const glm::dvec3> releasing() const { return releasing_; }
  [[nodiscard]] double release_time_s() const { return release_s_; }
  /// Replaces the fading load (one per node, or empty), fading over `time_s` from now: a
  /// lattice built again carries what the old one had still to let go of.
  void set_releasing(std::vector<glm::dvec3> load, double time_s);
  /// Builds the step's matrix now instead of in the first advance(), so that no step allocates
  /// (a volume that only gives forces never needs one).
  void build_step_matrix();
  [[nodiscard]] double finest_cell_m() const { return finest_cell_m_; }
  [[nodiscard]] double youngs_modulus_Pa() const { return youngs_Pa_; }

 private:
  struct Solver;
  /// The forces at the current positions (elements and contact, into the solver's force) and,
  /// with_matrix, the Newton matrix; the probe's force, contacts and penetration into `out`.
  void assemble(std::span<const EmbeddedPoint> points, const glm::dvec3& centre, double radius,
                double penalty, bool with_matrix, PressResult& out);
  /// The elements' forces at the current positions into the solver's force and, with_matrix,
  /// their corotated stiffness times `scale` into its matrix (zeroed first), each cell's warped
  /// with a rotation within warp_tolerance of its own (0: exactly its own).
  void assemble_elements(bool with_matrix, double warp_tolerance, double scale);
  void add_cell_matrix(std::size_t c, const glm::dmat3& r, double warp_tolerance, float scale);
  HexLattice lattice_;
  ElasticLaw law_;
  double mu_ = 0.0, lambda_ = 0.0;
  double youngs_Pa_ = 0.0;
  double retardation_s_ = 0.0;
  double finest_cell_m_ = INFINITY;  ///< the lattice's smallest cell side
  std::vector<glm::dvec3> x_;
  std::vector<glm::dvec3> v_;
  std::vector<double> mass_;
  std::vector<std::uint8_t> held_;
  std::vector<std::int32_t> hanging_index_;  ///< per node: its entry in lattice_.hanging, or -1
  glm::dvec3 held_velocity_{0.0};
  double tension_Pa_ = 0.0;
  std::vector<glm::dvec3> surroundings_;  ///< per node, N
  std::vector<glm::dvec3> releasing_;     ///< per node, N: fading (fade_in_from)
  double release_s_ = 0.0;
  std::vector<double> multipliers_;  ///< per surface point, N
  std::unique_ptr<Solver> solver_;
};

}  // namespace bisturi::sim
