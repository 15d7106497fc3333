#pragma once
// Backward Euler for the mass-spring model, one Newton-type step per (sub)step, solved by a
// Jacobi-preconditioned conjugate gradient warm-started with the previous step's velocity
// change (docs/sim/integrator.md says why, with the measurements).
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
// stored once per topology (and set of free vertices) as compressed rows of neighbours grouped
// by stiffness class and applied by gathering. Penalty contacts (SoftBody::add_contact) add
// their k n n^T blocks to it. a is the mass-proportional drag. The volume term is explicit.
// Anchored, kinematic and massless vertices are constraints: the solve runs over the free
// vertices only, in a compact numbering with four lanes (x, y, z, pad) per vertex. Every loop
// runs in a fixed order on one thread (reductions keep one partial sum per lane, combined in a
// fixed order): the same inputs give bit-identical states.
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
  int max_cg_iterations = 12;
  double cg_relative_tolerance = 1e-4;
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

 private:
  /// The springs of one body generation as arrays, and the matrix's neighbour rows restricted to
  /// the free vertices (neither anchored, kinematic nor massless): the solve runs over those only,
  /// in a compact numbering. The compact part is rebuilt when the set of free vertices changes.
  struct Structure {
    std::uint64_t generation = 0;
    std::vector<std::uint32_t> a, b;  ///< spring ends
    std::vector<double> rest, k;
    std::vector<std::uint8_t> spring_class;  ///< index into k_class
    std::vector<double> k_sum;               ///< per vertex: sum of its springs' k
    std::vector<double> degree;              ///< per vertex: number of springs
    double k_class[4] = {0.0, 0.0, 0.0, 0.0};
    // The free vertices: mask per vertex (1 = free), compact -> vertex, vertex -> compact.
    std::vector<std::uint8_t> free_mask;
    std::vector<std::uint32_t> vertex, compact;
    /// 4 (free count) + 1 offsets into col: row r's neighbours of stiffness class k are
    /// col[row[4 r + k] .. row[4 r + k + 1]).
    std::vector<std::uint32_t> row;
    std::vector<std::uint32_t> col;  ///< free neighbours' compact indices
  };
  Structure& structure(const SoftBody& body);
  /// Rebuilds st's compact rows when free_ differs from the mask they were built for.
  static void update_free_rows(Structure& st, const std::vector<std::uint8_t>& free_mask);
  /// One backward Euler substep of length h; kinematic targets are interpolated by fraction.
  /// When energy_out is given, it receives the total energy of the state the substep starts from.
  void substep(SoftBody& body, Structure& st, const IntegratorOptions& options, double h,
               double fraction, StepStats& stats, double* energy_out);
  /// Springs + volume term at the current positions.
  static double elastic(const SoftBody& body, const Structure& st);
  /// Empty when the state is fine, else the reason.
  std::string check(const SoftBody& body, const Structure& st, const IntegratorOptions& options,
                    double energy_before, bool energy_check) const;

  std::vector<Structure> structures_;
  std::vector<glm::dvec3> saved_x_, saved_v_;
  std::vector<glm::dvec3> f_, grad_;  ///< per vertex: spring forces, volume gradient (x 6)
  std::vector<std::uint8_t> free_;
  // Solver vectors over the free vertices: x, y, z and a zero pad per free vertex.
  std::vector<double> rhs_, dv_, r_, p_, ap_, diag_, inv_diag_;
  struct Contact {
    std::uint32_t c;  ///< compact index
    double nx, ny, nz, k;
  };
  std::vector<Contact> contacts_;
};

}  // namespace bisturi::sim
