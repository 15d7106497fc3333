#pragma once
// Backward Euler for the mass-spring model, one Newton-type step per (sub)step, solved by a
// conjugate gradient preconditioned by block Jacobi (each row's 3 x 3 diagonal block) plus a
// coarse correction over aggregates of nearby vertices (two-level), in float lanes (double for
// tolerances below 1e-5) while the state stays in double (docs/sim/integrator.md says why, with
// the measurements).
//
//   (M (1 + h a) + h C + h^2 H) dv = h (f(x, v) - h H v),   v += dv,   x += h v
//
// H is each spring's Hessian with its transverse part clamped at zero, k u u^T +
// k max(0, 1 - L/|d|) (I - u u^T), and C its damping c u u^T (SpringHessian::Clamped): a
// positive semi-definite 3 x 3 block per spring, a I + s s^T, made by the spring pass each
// substep and applied by gathering neighbour differences over rows of neighbours stored once per
// topology (and set of free vertices). The haptic force then converges with the step length.
// SpringHessian::Bound uses k I per spring (and c I) instead: a constant weighted Laplacian and a
// majorise-minimise step that never overshoots, but a transverse viscosity h k per spring that
// makes the 1 ms tissue several times stiffer than the converged one. The coarse level is built
// on the bound either way (it is factored once per topology and h). Penalty contacts
// (SoftBody::add_contact) add their k n n^T blocks. a is the mass-proportional drag. The
// volume term is explicit. Anchored, kinematic and massless vertices are constraints: the solve
// runs over the free vertices only, in a compact numbering with four lanes (x, y, z, pad) per
// vertex; a spring to one of them weighs on its free end's diagonal block. Every loop runs in a
// fixed order (reductions keep one partial sum per lane, combined in
// a fixed order, and the AVX2 and baseline clones of the hot loops round alike): the same inputs
// give bit-identical states. With IntegratorOptions::threads > 1 the spring passes and the
// solve's matrix products are split over a team of threads in parts fixed by the thread count,
// their partial sums added in member order: still bit-identical run to run for that count.
//
// Sleeping (IntegratorOptions::sleeping): the free vertices are grouped into the coarse level's
// aggregates. An aggregate whose residual force, and the force one more step of its motion would
// add, stayed under the solver's absolute tolerance for sleep_steps steps is stopped and held
// fixed, like an anchor: the solve, the spring pass and the right-hand side run over the awake
// aggregates only, and a body asleep entirely skips its step. A sleeping aggregate wakes when its
// residual can exceed three tolerances: an external load on it (add_force, add_contact), the
// springs to a moving awake neighbour (evaluated every step on the border of the awake region),
// or a change of the pressure since it fell asleep (bounded per aggregate, no per-vertex work);
// anchoring, grasping and cutting wake the whole body (docs/sim/integrator.md, "Sleeping").
//
// Multirate (IntegratorOptions::far_field_interval, experimental): a step solves the region
// around the loads with dt, the rest held, and a slice of one longer step over the whole body
// that lands a period later; it costs a fraction of a full step, and its far field relaxes as a
// body stepped with the longer step does (integrator_multirate.cpp, integrator_far_field.cpp;
// docs/sim/integrator.md, "Multirate stepping").
//
// The guard: after a step, a state with a non-finite value, a vertex faster than max_speed, or
// an energy rise larger than the work of the external forces plus a tolerance is a divergence.
// The body is rolled back to the state before the step and the step is retried with 2, 4, 8...
// substeps; when the last retry fails too, the body is restored and frozen (zero velocities, no
// forces). Every rollback and freeze is reported as a SimEvent; nothing is thrown.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

/// The springs' stiffness in the solve's matrix and in its h^2 H v term.
enum class SpringHessian : std::uint8_t {
  /// Each spring's Hessian with its transverse part clamped at zero (positive semi-definite):
  /// the linearised backward Euler step, whose haptic force converges with the step length.
  Clamped,
  /// The bound k I per spring (and c I for its damping): a majorise-minimise step that never
  /// overshoots, but acts as a transverse viscosity h k per spring (docs/sim/integrator.md).
  Bound,
};

struct IntegratorOptions {
  double dt_s = 1e-3;
  glm::dvec3 gravity_m_s2{0.0, 0.0, -9.81};
  /// With the two-level preconditioner; with cg_coarse_level off (Jacobi alone, which leaves
  /// the smooth modes to the CG), use 12.
  int max_cg_iterations = 6;
  /// Two-level preconditioner (Jacobi plus a coarse correction over aggregates of vertices,
  /// factored once per topology, set of free vertices and substep length); off: Jacobi alone.
  bool cg_coarse_level = true;
  double cg_relative_tolerance = 1e-4;
  SpringHessian spring_hessian = SpringHessian::Clamped;
  /// Start the solve from the last step's velocity change instead of zero. Off: with the clamped
  /// Hessian it saves nothing at 6 iterations (the solve runs to its cap either way) and with 4
  /// it led to guard rollbacks (docs/sim/integrator.md). The bound Hessian converges from it in
  /// fewer iterations.
  bool cg_warm_start = false;
  /// The solve also stops when the residual force is small in absolute terms: its RMS over the
  /// free vertices below cg_weight_fraction x the RMS of their weights (m |g|), or below
  /// cg_force_floor_N per vertex (for scenes without gravity). A body at rest then costs 0-2
  /// iterations instead of chasing a relative residual on a right-hand side that is rounding
  /// noise (docs/sim/integrator.md: the static error this leaves is that fraction of the sag).
  double cg_weight_fraction = 1e-3;
  double cg_force_floor_N = 1e-8;
  /// Retries with 2^1 .. 2^max_retry_halvings substeps before freezing.
  int max_retry_halvings = 3;
  double max_speed_m_s = 20.0;
  /// Allowed energy rise beyond the external work: energy_jump_J + energy_jump_relative * |E|.
  double energy_jump_J = 1e-3;
  double energy_jump_relative = 0.05;
  /// Aggregates of vertices at rest stop and cost nothing until a load, a moving neighbour or a
  /// pressure change wakes them (see above). Off: every free vertex is solved every step.
  bool sleeping = true;
  /// Steps in a row an aggregate must stay under the sleep thresholds before it sleeps.
  int sleep_steps = 10;
  /// Threads for the spring pass and the solve's matrix products (the integrator keeps a team
  /// of threads - 1 helpers). The parts are fixed by the thread count, so a run is bit-identical
  /// to another with the same count; different counts round differently (reductions split).
  unsigned threads = 1;
  /// Multirate stepping (docs/sim/integrator.md, "Multirate stepping"). With far_field_interval =
  /// N > 1 a step solves the near region - the aggregates with a loaded vertex (an external
  /// force or a contact), widened by near_rings rings of aggregates - with a step of dt, the
  /// rest of the body held. The far field is one single-rate step of N dt over the whole body,
  /// made on a copy of it in slices over the N steps of a period (a fiber on the calling thread:
  /// one core) and applied to the vertices outside the near region over the next period, a
  /// block of aggregates per step (the near region's neighbours at the period's start).
  /// A step then costs the region and an N-th of a full step, and runs stay bit-identical (the
  /// result does not depend on where the slices end). An aggregate stays near until it has been
  /// without a load for near_linger_steps steps, and leaves at a period's start. Sleeping is
  /// off in this mode, its solves run on the calling thread, and a body with kinematic vertices
  /// (a grasp) takes single-rate steps. 1 (the default): every free vertex every step.
  /// Opt-in (a scene's [simulation] far_field_interval): N = 32 brings a 20k-vertex organ's
  /// median step under 1 ms on one core, not its p99 (docs/sim/integrator.md, "Current
  /// figures"), at a cost: the far field lags a period behind and relaxes as a body stepped with
  /// N dt does, more slowly than with dt.
  int far_field_interval = 1;
  int near_rings = 1;
  int near_linger_steps = 1000;
  /// Multirate: the far field's job runs in a step until the step has taken this long (from
  /// the start of its multirate part, which is nearly all of it), or for its even share of the
  /// job's time left if that is longer. Steps whose near solve was quick then take more of the job,
  /// which ends early in its period, and the slow ones take only their share: the step times even
  /// out below the budget. 0: the even share alone. Timing only: results do not depend on it.
  double far_step_budget_s = 0.4e-3;

  bool operator==(const IntegratorOptions&) const = default;
};

enum class SimEventKind : std::uint8_t { RolledBack, Frozen };

struct SimEvent {
  SimEventKind kind = SimEventKind::RolledBack;
  std::uint32_t body = 0;  ///< index of the body in its world
  std::uint64_t step = 0;  ///< step counter of the world (or the caller)
  int substeps = 1;        ///< substeps of the attempt that failed
  std::string reason;      ///< "non-finite state", "speed ...", "energy rose ..."
};

struct StepStats {
  int substeps = 1;                ///< of the attempt that was kept
  int cg_iterations = 0;           ///< summed over substeps
  double relative_residual = 0.0;  ///< of the last solve
  bool rolled_back = false;
  bool frozen = false;
  std::uint32_t free_vertices = 0;   ///< neither anchored, kinematic nor massless
  std::uint32_t awake_vertices = 0;  ///< free vertices that were solved (not sleeping)
  /// The step started from the force pass the last one took at its end (nothing had changed).
  bool reused_end_pass = false;
};

/// The integrator's solver structures, scratch and thread team (sim/src/integrator_state.h).
struct ImplicitEulerState;

class ImplicitIntegrator {
 public:
  ImplicitIntegrator();
  ~ImplicitIntegrator();
  /// Not copyable: its thread team and a multirate far field's job belong to one integrator.
  /// A moved-from integrator may only be assigned to or destroyed.
  ImplicitIntegrator(const ImplicitIntegrator&) = delete;
  ImplicitIntegrator& operator=(const ImplicitIntegrator&) = delete;
  ImplicitIntegrator(ImplicitIntegrator&&) noexcept;
  ImplicitIntegrator& operator=(ImplicitIntegrator&&) noexcept;

  /// Advances `body` by options.dt_s with the guard; events are appended to `events` tagged with
  /// body_index and step. External forces are consumed (cleared). A frozen body does not move.
  StepStats step(SoftBody& body, const IntegratorOptions& options, std::vector<SimEvent>& events,
                 std::uint32_t body_index = 0, std::uint64_t step = 0);
  /// Builds what the first step of `body` would build lazily (solver structure for its current
  /// topology and set of free vertices, scratch buffers), so that step costs what later ones do.
  /// Optional; call again after anchoring or a cut to move that work off the next step.
  void prepare(SoftBody& body, const IntegratorOptions& options = {});
  /// Wakes every sleeping vertex of `body`: for callers that move vertices directly
  /// (set_position, set_velocity, positions()), which the integrator does not see.
  void wake(const SoftBody& body);
  /// A consistency check for tests: empty when the free system the integrator holds for the
  /// body's current generation is, array for array, what a build from scratch gives (after cuts
  /// it is updated around them), else what differs. Call after a step or prepare().
  [[nodiscard]] std::string check_free_system(const SoftBody& body);
  /// How many free systems were updated around a cut rather than built again.
  [[nodiscard]] std::uint64_t systems_updated() const;

 private:
  std::unique_ptr<ImplicitEulerState> impl_;
};

}  // namespace bisturi::sim
