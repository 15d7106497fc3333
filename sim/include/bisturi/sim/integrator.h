#pragma once
// Backward Euler for the mass-spring model, one Newton-type step per (sub)step, solved by a
// conjugate gradient warm-started with the previous step's velocity change and preconditioned
// by Jacobi plus a coarse correction over aggregates of nearby vertices (two-level), in float
// lanes (double for tolerances below 1e-5) while the state stays in double
// (docs/sim/integrator.md says why, with the measurements).
//
//   (M (1 + h a) + h C + h^2 H) dv = h (f(x, v) - h H v),   v += dv,   x += h v
//
// H is not the springs' exact Hessian but the bound k I per spring (the Hessian of
// k/2 (|d| - L)^2 never exceeds k I: its axial eigenvalue is k, its transverse one
// k (1 - L/|d|) < k). The quadratic model then lies above the true incremental potential, so
// each step lowers it (a majorise-minimise step, as in projective dynamics) however far the
// tissue is pushed out of its plane, where the exact Hessian has no transverse stiffness at rest
// and the linearised step overshoots. The same bound is used for the damping (c I per spring).
// With both, the matrix is a constant weighted graph Laplacian (the same for x, y and z): it is
// stored once per topology (and set of free vertices) as rows of neighbours tagged with their
// stiffness class and applied by gathering neighbour differences. Penalty contacts
// (SoftBody::add_contact) add their k n n^T blocks to it. a is the mass-proportional drag. The
// volume term is explicit. Anchored, kinematic and massless vertices are constraints: the solve
// runs over the free vertices only, in a compact numbering with four lanes (x, y, z, pad) per
// vertex. Every loop runs in a fixed order on one thread (reductions keep one partial sum per lane,
// combined in a fixed order, and the AVX2 and baseline clones of the hot loops round alike): the
// same inputs give bit-identical states.
//
// The guard: after a step, a state with a non-finite value, a vertex faster than max_speed, or
// an energy rise larger than the work of the external forces plus a tolerance is a divergence.
// The body is rolled back to the state before the step and the step is retried with 2, 4, 8...
// substeps; when the last retry fails too, the body is restored and frozen (zero velocities, no
// forces). Every rollback and freeze is reported as a SimEvent; nothing is thrown.

#include <cstdint>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

struct IntegratorOptions {
  double dt_s = 1e-3;
  glm::dvec3 gravity_m_s2{0.0, 0.0, -9.81};
  /// 6 two-level iterations leave a smaller residual than 12 Jacobi ones did (measured in
  /// docs/sim/integrator.md); with cg_coarse_level off, use 12.
  int max_cg_iterations = 6;
  /// Two-level preconditioner (Jacobi plus a coarse correction over aggregates of vertices,
  /// factored once per topology, set of free vertices and substep length); off: Jacobi alone.
  bool cg_coarse_level = true;
  double cg_relative_tolerance = 1e-4;
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
};

class ImplicitIntegrator {
 public:
  /// Advances `body` by options.dt_s with the guard; events are appended to `events` tagged with
  /// body_index and step. External forces are consumed (cleared). A frozen body does not move.
  StepStats step(SoftBody& body, const IntegratorOptions& options, std::vector<SimEvent>& events,
                 std::uint32_t body_index = 0, std::uint64_t step = 0);
  /// Builds what the first step of `body` would build lazily (solver structure for its current
  /// topology and set of free vertices, scratch buffers), so that step costs what later ones do.
  /// Optional; call again after anchoring or a cut to move that work off the next step.
  void prepare(SoftBody& body, const IntegratorOptions& options = {});

 private:
  /// The springs of one body generation as arrays, and the matrix's neighbour rows restricted to
  /// the free vertices (neither anchored, kinematic nor massless): the solve runs over those only,
  /// in a compact numbering. The compact part is rebuilt when the set of free vertices changes.
  struct Structure {
    std::uint64_t generation = 0;
    std::vector<std::uint32_t> a, b;  ///< spring ends
    std::vector<double> rest, k;
    std::vector<std::uint8_t> spring_class;  ///< index into k_class
    double k_class[4] = {0.0, 0.0, 0.0, 0.0};
    // The free vertices: mask per vertex (1 = free), compact -> vertex, vertex -> compact.
    std::vector<std::uint8_t> free_mask;
    std::vector<std::uint32_t> vertex, compact;
    /// 4 (free count) + 1 offsets into col: row r's neighbours of stiffness class k are
    /// col[row[4 r + k] .. row[4 r + k + 1]).
    std::vector<std::uint32_t> row;
    std::vector<std::uint32_t> col;  ///< free neighbours' compact indices
    /// The same neighbours for the product: nf + 1 offsets into pcol, whose entries are
    /// compact index | class << 30, each row padded to an even length with itself.
    std::vector<std::uint32_t> prow, pcol;
    /// Per free row and class: springs to constrained vertices (they weigh on the diagonal only).
    std::vector<std::uint32_t> fixed_count;  ///< 4 per free row
    /// Springs as copies in two sets, each padded to a multiple of 4 with null springs: those
    /// with a free end (their forces are needed) and those between two constrained vertices,
    /// which do not move during a step (their energy is taken once per step, no forces).
    struct SpringSet {
      std::vector<std::uint32_t> a, b;
      std::vector<double> rest, k;
      std::size_t count = 0;  ///< real springs (a.size() is padded)
    };
    SpringSet active, fixed;
    /// The coarse level of the preconditioner: free rows grouped into aggregates of nearby
    /// vertices (agg: row -> aggregate), and the Cholesky factor of the aggregated matrix
    /// P^T A P (contacts left out), packed lower rows with the diagonal inverted, for the h it
    /// was built with (coarse_h < 0: none yet).
    std::vector<std::uint32_t> agg;
    std::uint32_t coarse_count = 0;
    double coarse_h = -1.0;
    std::vector<double> coarse;
    std::vector<float> coarse_f;
  };
  Structure& structure(const SoftBody& body);
  /// Rebuilds st's compact rows when free_ differs from the mask they were built for.
  static void update_free_rows(Structure& st, const std::vector<std::uint8_t>& free_mask);
  /// (Re)factors st's coarse matrix for substep length h when it was built for another h.
  void update_coarse(Structure& st, const SoftBody& body, double h);
  /// free_[i] = 1 for a vertex the solve moves (mass, not anchored, not kinematic).
  void free_mask(const SoftBody& body);
  /// One backward Euler substep of length h; kinematic targets are interpolated by fraction.
  /// When energy_out is given, it receives the total energy of the state the substep starts from
  /// and fixed_energy_out the part of it in springs between constrained vertices.
  void substep(SoftBody& body, Structure& st, const IntegratorOptions& options, double h,
               double fraction, StepStats& stats, double* energy_out, double* fixed_energy_out);
  /// The CG over the free vertices in T (float: half the memory traffic; double for tolerances
  /// float cannot reach). Reads rhs_, diag_, self_, inv_diag_, contacts_ and the warm start in
  /// dv_; leaves the solution in dv_.
  template <class T>
  void solve(const Structure& st, const double (&w)[4], int max_iterations, double rel_tol2,
             double abs_tol2, StepStats& stats);
  /// Empty when the state is fine, else the reason.
  std::string check(const SoftBody& body, const Structure& st, const IntegratorOptions& options,
                    double energy_before, double fixed_energy, bool energy_check) const;

  std::vector<Structure> structures_;
  std::vector<glm::dvec3> saved_x_, saved_v_;
  std::vector<glm::dvec3> f_, grad_;  ///< per vertex: spring forces, volume gradient (x 6)
  std::vector<std::uint8_t> free_;
  // Solver data over the free vertices, four lanes (x, y, z, zero pad) per vertex: the
  // right-hand side, the diagonal and its inverse (contact blocks included), and the part of the
  // diagonal that is not a free neighbour's weight (mass, drag, springs to constrained vertices).
  std::vector<double> rhs_, diag_, self_, inv_diag_, dv_;
  std::vector<float> fbuf_;       ///< float CG vectors (r, p, ap and copies of the above)
  std::vector<double> dbuf_;      ///< double CG vectors
  std::vector<float> cbuf_f_;     ///< coarse vectors (rc, xc) of the float solve
  std::vector<double> cbuf_d_;    ///< and of the double solve
  std::vector<double> contacts_;  ///< 5 per contact: compact index, nx, ny, nz, h^2 k
};

}  // namespace bisturi::sim
