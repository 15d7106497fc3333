#pragma once
// The implicit integrator's state (ImplicitEulerState, behind ImplicitIntegrator): the solver
// structures per body generation, the step's scratch arrays and thread team, and the steps'
// pieces, defined across integrator.cpp (the step, the passes, the solve and the guard),
// integrator_system.cpp (the free system and its coarse level), integrator_sleep.cpp,
// integrator_multirate.cpp and integrator_far_field.cpp (docs/sim/integrator.md).

#include <chrono>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

class StepThreads;

struct ImplicitEulerState {
  // ---- The public methods' bodies (ImplicitIntegrator forwards to them) ----
  StepStats step(SoftBody& body, const IntegratorOptions& options, std::vector<SimEvent>& events,
                 std::uint32_t body_index, std::uint64_t step_index);
  void prepare(SoftBody& body, const IntegratorOptions& options);
  void wake(const SoftBody& body);
  [[nodiscard]] std::string check_free_system(const SoftBody& body);

  /// A linear system over a set of solved vertices (the free ones, or the awake ones when some
  /// sleep), in a compact numbering, with its spring sets and coarse level.
  struct System {
    /// Unique over every build of any system (build_system): a key for data taken over it.
    std::uint64_t id = 0;
    // compact -> vertex, vertex -> compact (kNotFree outside the set).
    std::vector<std::uint32_t> vertex, compact;
    /// The solved neighbours of each row: count + 1 offsets into pcol, whose entries are
    /// compact index | stiffness class << 30, grouped by class, each row padded to an even
    /// length with itself.
    std::vector<std::uint32_t> prow, pcol;
    std::vector<std::uint32_t> fill;                ///< scratch of the build: per row and class
    std::vector<std::uint32_t> prow_old, pcol_old;  ///< scratch of update_system
    /// Per row and class (4 per row): springs to solved neighbours, and springs to vertices
    /// held fixed (they weigh on the diagonal only).
    std::vector<std::uint32_t> free_count, fixed_count;
    /// Springs as copies in sets, each padded to a multiple of 4 with null springs: those with a
    /// solved end (their forces are needed), those with none, which do not move during a step
    /// (their energy is taken once per set), and among those the ones with an end on the border
    /// of the awake region (their forces tell whether a sleeping vertex must wake).
    struct SpringSet {
      std::vector<std::uint32_t> a, b;
      std::vector<double> rest, k;
      std::size_t count = 0;  ///< real springs (a.size() is padded)
    };
    SpringSet active, fixed, halo;
    /// Per entry of pcol: the index in `active` of its spring (kNotFree for the padding); and
    /// for each active spring from a solved row to a held vertex, the row and the spring (its
    /// block weighs on that row's diagonal).
    std::vector<std::uint32_t> entry_spring, held_springs;
    /// Sleeping free vertices with a spring or a triangle to an awake one.
    std::vector<std::uint32_t> border;
    double fixed_energy = 0.0;
    bool fixed_energy_valid = false;
    /// The coarse level of the preconditioner: rows grouped into aggregates of nearby vertices
    /// (agg: row -> aggregate), and the Cholesky factor of the aggregated matrix P^T A P
    /// (contacts left out) in skyline form: row I holds columns coarse_first[I]..I from
    /// coarse[coarse_start[I]], the diagonal inverted; for the h it was built with (coarse_h < 0:
    /// none yet).
    std::vector<std::uint32_t> agg;
    std::uint32_t coarse_count = 0;
    double coarse_h = -1.0;
    std::vector<double> coarse;
    std::vector<float> coarse_f;
    std::vector<std::uint32_t> coarse_first, coarse_start;
    /// The bound matrix's diagonal for one substep length, kept while the system, h and the
    /// team stay (it changes with nothing else): per row its value (with k I per spring: the
    /// sleep test's stopping force), the mass part m (1 + h a), its float copy, and the rows'
    /// summed squared masses.
    struct Diagonal {
      std::uint64_t system = 0;  ///< the System::id it was built for (0: none)
      double h = 0.0;
      unsigned members = 0;
      std::vector<double> value, self;
      std::vector<float> self_f;
      double weight2 = 0.0;
    } diagonal;
    /// Scratch of update_coarse: the diagonal of P^T A P and one row of it, and the entries
    /// between aggregates left of the diagonal (aggregate J | class << 30) by aggregate
    /// (link_start offsets into links).
    std::vector<double> coarse_diag, coarse_row;
    std::vector<std::uint32_t> link_start, links, link_scratch;
  };
  /// 6 V of a body by groups of triangles (multirate): a group per aggregate of the free system
  /// (the triangles whose first free corner is in it) and one for the triangles without a free
  /// corner. The volume is their sum in group order; a region's solve recomputes the groups it
  /// moved.
  struct MultirateGroups {
    std::vector<std::uint32_t> start, tris;  ///< per group (start offsets into tris)
    std::vector<std::uint32_t> tri_group;    ///< per triangle
    std::vector<double> six_v;               ///< per group
    std::vector<double> tri_six_v;           ///< per triangle
    bool valid = false;
    [[nodiscard]] double total() const;
    /// The listed triangles' 6 V at positions x, then the listed groups' sums.
    void update(const std::vector<std::uint32_t>& triangles,
                const std::vector<std::uint32_t>& groups_to_sum,
                const std::vector<std::uint32_t>& indices, const std::vector<glm::dvec3>& x);
    /// Every triangle and group at positions x.
    void update_all(const std::vector<std::uint32_t>& indices, const std::vector<glm::dvec3>& x);
  };
  /// The multirate far field: a copy of the body advanced by a solver of its own in a fiber.
  struct FarField;
  /// The solver structure of one body generation: the system over its free vertices (neither
  /// anchored, kinematic nor massless; rebuilt when that set changes), and the sleep state of
  /// the free system's aggregates with the system over the awake ones.
  struct Structure {
    std::uint64_t generation = 0;
    std::uint64_t lineage = 0;  ///< the body's (SoftBody::lineage)
    /// The body's springs, read in place (a copy cost 1 ms of a cut's preparation at 20k
    /// vertices): set by structure() for the step or preparation in progress.
    const std::vector<Spring>* springs = nullptr;
    /// The springs' stiffness classes in order of first appearance (set by build_system).
    double k_class[4] = {0.0, 0.0, 0.0, 0.0};
    std::vector<std::uint8_t> free_mask;  ///< per vertex, 1 = free
    /// After a local refresh of the body's springs (SoftBody::last_spring_change) from the
    /// generation `full` was built for: the mask it was built with and the vertices whose springs
    /// may differ, so that update_system can update it around them.
    bool local_change = false;
    std::vector<std::uint8_t> old_mask;
    std::vector<std::uint32_t> changed_vertices;
    std::vector<std::uint8_t> dirty;  ///< scratch of update_system: per vertex
    System full;
    /// Per aggregate of `full`: its rows (agg_start offsets into agg_rows), awake flag, steps
    /// in a row under the sleep thresholds, and for a sleeping one the pressure factor it fell
    /// asleep with and the bounds of its residual and pressure gradient (in tolerances).
    std::vector<std::uint32_t> agg_start, agg_rows;
    std::vector<double> agg_mass2;  ///< sum of the squared masses of its vertices
    std::vector<std::uint8_t> awake;
    std::vector<std::uint16_t> quiet;
    std::vector<double> sleep_p6, sleep_residual, sleep_gradient;
    /// Per aggregate, sums over its vertices of the last substep's squared residual force, force
    /// that stopping them within a step takes, and pressure gradient.
    std::vector<double> step_residual, step_speed, step_gradient;
    std::uint32_t asleep = 0;  ///< sleeping aggregates
    System part;               ///< the awake vertices' system (when asleep > 0)
    bool part_dirty = true;
    /// Multirate stepping (IntegratorOptions::far_field_interval): regions of the free system
    /// solved on their own, and the volume kept by groups of triangles.
    struct Region {
      System sys;  ///< over the region's rows; the other vertices are held
      /// The triangles with a corner among the rows (their gradient is needed), the vertices
      /// the region's passes write (rows, ends of its springs, corners of its triangles), and
      /// the volume groups of its triangles (their sums change when the rows move).
      std::vector<std::uint32_t> tris, touched, groups;
      bool dirty = true;
    };
    struct Multirate {
      std::uint64_t system = 0;  ///< the full System::id it was made for (0: none)
      /// Steps taken in this mode (for the near region's linger time), and the tick the far
      /// field's current run of periods started at.
      std::uint64_t tick = 0, period_start = 0;
      /// Per aggregate of the full system: whether it is in the near region, the last tick it
      /// had a load, and whether it is wanted there this tick.
      std::vector<std::uint8_t> near, want;
      std::vector<std::uint64_t> loaded_tick;
      /// The aggregates' neighbours (adj_start offsets into adj), and the triangles with a free
      /// corner in each (tri_start offsets into tris).
      std::vector<std::uint32_t> adj_start, adj, tri_start, tris;
      /// The aggregates in the order the far field's blocks take them (Morton order of their
      /// centres: a block is a compact piece of the surface).
      std::vector<std::uint32_t> block_order;
      Region near_region;
      MultirateGroups groups;
      /// The far field's copy of the body, its solver and its job (integrator_far_field.cpp).
      std::shared_ptr<FarField> far;
      /// The copy's state no longer follows the body's (single-rate steps, a freeze).
      bool far_stale = false;
      std::uint64_t state_edits = 0;  ///< SoftBody::state_edits() after the last tick
      /// SoftBody::constraint_edits() and derived_generation() of the last constraint pass.
      std::uint64_t constraint_edits = 0, constraint_generation = 0;
      std::vector<std::uint32_t> ring, next_ring;  ///< scratch of update_near
      /// Scratch of far_apply_aggregate: the triangles and groups to sum again, the groups'
      /// marks.
      std::vector<std::uint32_t> moved_tris, moved_groups;
      std::vector<std::uint8_t> group_marked;
    } multirate;
    /// The force pass taken at the end of the last accepted step, at its end state and for a
    /// substep of dt (the guard's energies come out of it): the next step's first substep uses
    /// it instead of its own while the state, the system and the team are what they were.
    struct Ahead {
      bool valid = false;
      std::uint64_t state_edits = 0;  ///< SoftBody::state_edits() after the step
      std::uint64_t system = 0;       ///< System::id of the springs it took
      double h = 0.0;
      unsigned members = 0;
      double elastic = 0.0;             ///< the springs' energy, fixed ones included
      double six_v = 0.0;               ///< 6 V (closed bodies)
      std::vector<glm::dvec3> f, grad;  ///< spring forces, volume gradient (swapped with f_, grad_)
      std::vector<float> blocks;        ///< the springs' blocks (swapped with blocks_)
    } ahead;
  };
  Structure& structure(const SoftBody& body);
  /// Rebuilds st's free system when free_mask differs from the mask it was built for (every
  /// vertex wakes).
  void update_free_rows(Structure& st, const std::vector<std::uint8_t>& free_mask,
                        const std::vector<double>& masses);
  /// Builds sys over the rows of the full system's aggregates with flags[a] set, its coarse
  /// level those aggregates renumbered in order; leaves the vertices' mask in mask_.
  void build_over_aggregates(Structure& st, System& sys, const std::vector<std::uint8_t>& flags);
  /// Builds sys over the vertices with mask[i] = 1 (and st.k_class from st's springs).
  static void build_system(Structure& st, System& sys, const std::vector<std::uint8_t>& mask);
  /// build_system's result for st.full after a local change of the springs (st.local_change),
  /// made by updating the rows of the changed vertices only: the same arrays, entry for entry.
  /// Returns false when it cannot (a vertex's constraint changed, a new stiffness or another
  /// order of the classes): sys is then left half made, for build_system to make again.
  static bool update_system(Structure& st, System& sys, const std::vector<std::uint8_t>& mask);
  /// build_system's passes over the springs: the rows' counts per class (free_count and
  /// fixed_count, zeroed) and the stiffness classes found on the way (free slots NaN), returning
  /// the springs with a solved end; then the spring sets and the rows' entries (from sys.fill;
  /// with AllRows false only the rows of vertices with dirty[v] set).
  static std::size_t count_entries(const std::vector<Spring>& springs, System& sys,
                                   double (&classes)[4]);
  template <bool AllRows>
  static void fill_entries(const std::vector<Spring>& springs, System& sys,
                           const double (&classes)[4], const std::uint8_t* dirty);
  /// sys.entry_spring and sys.held_springs from its rows and active springs (after a build or
  /// an update).
  static void map_entries(const Structure& st, System& sys);
  /// Groups the system's rows into aggregates of nearby vertices.
  static void aggregate(System& sys);
  /// (Re)factors sys's coarse matrix (over its aggregates, which it must have) for substep
  /// length h when it was built for another h.
  static void update_coarse(System& sys, const Structure& st, const SoftBody& body, double h);
  /// update_coarse's parts: the diagonal of P^T A P (coarse_diag) and its links; row I left of
  /// the diagonal into coarse_row (returning its first column written); and the factor's row I
  /// (columns first..I) from them.
  static void collect_coarse(System& sys, const SoftBody& body, const double (&w)[4], double h);
  static std::size_t assemble_coarse_row(System& sys, const double (&w)[4], std::size_t row);
  static void factor_coarse_row(System& sys, std::size_t row, std::size_t first);
  // ---- Sleeping (integrator_sleep.cpp) ----
  /// The system to solve: the free one while every aggregate is awake, else the awake one.
  System& system(Structure& st, const SoftBody& body);
  static void wake_all(Structure& st);
  /// True when every aggregate sleeps and nothing can wake one this step (same constraints, no
  /// external load on a free vertex): the step then leaves the state as it is.
  bool sleeps_entirely(const Structure& st, const SoftBody& body);
  static void wake_aggregate(Structure& st, std::uint32_t aggregate);
  /// Wakes the aggregates of the vertices with an external load (force or contact).
  void wake_loaded(Structure& st, const SoftBody& body);
  /// Wakes sleeping aggregates whose residual force can exceed the tolerance at the state the
  /// substep starts from (f_, grad_ and p6 of its force pass); true when one woke.
  bool wake_by_forces(Structure& st, const System& sys, const SoftBody& body,
                      const IntegratorOptions& options, double p6);
  /// After an accepted step: counts the quiet steps of the awake aggregates and stops those
  /// that stayed quiet for options.sleep_steps.
  void update_sleep(Structure& st, SoftBody& body, const IntegratorOptions& options);
  /// The solver's absolute tolerance summed over an aggregate's vertices: the sum of the squared
  /// residual forces it allows there (options.cg_weight_fraction of the weights, the floor).
  static double tolerance2(const Structure& st, std::uint32_t aggregate,
                           const IntegratorOptions& options);
  /// free_[i] = 1 for a vertex the solve moves (mass, not anchored, not kinematic).
  void free_mask(const SoftBody& body);
  /// One backward Euler substep of length h; kinematic targets are interpolated by fraction.
  /// When energy_out is given, it receives the total energy of the state the substep starts from
  /// Returns the system it solved.
  /// When reuse_ahead is set, st.ahead's force pass stands for the substep's own if it was
  /// taken over the system the substep solves and for its h.
  System& substep(SoftBody& body, Structure& st, const IntegratorOptions& options, double h,
                  double fraction, StepStats& stats, double* energy_out, bool reuse_ahead);
  /// The next step's force pass taken at the end state (for a substep of dt) into st.ahead;
  /// returns the end state's elastic energy (springs and volume term) for the guard.
  double end_pass(Structure& st, System& sys, const SoftBody& body,
                  const IntegratorOptions& options);
  /// The spring forces of sys (and of its halo) into f_ (zeroed first); when energy is set,
  /// returns the elastic energy of every spring (the fixed ones' is kept in sys).
  double spring_pass(System& sys, const SoftBody& body, double h, bool energy);
  /// Adds the team members' arrays to `into` (in member order, each member a run of items).
  void add_parts(std::vector<glm::dvec3>& into, const std::vector<std::vector<glm::dvec3>>& parts);
  /// The volume term's gradient (6 dV/dx) into grad_, split over the team; returns 6 V.
  double volume_pass(const SoftBody& body);
  /// The energy of sys's fixed springs (which do not move while sys is in use), taken once.
  static double fixed_energy(System& sys, const SoftBody& body);
  /// The solve's matrix for this substep from the spring pass's blocks (blocks_): each entry's
  /// block (entry_blocks_), the held springs' diagonal blocks (held_blocks_) and the block
  /// Jacobi inverses of the rows' 3 x 3 diagonal blocks, contacts included (jinv_, jinv_f_).
  void block_rows(System& sys);
  /// st.diagonal for substep length h (rebuilt when stale).
  void update_diagonal(System& st, const SoftBody& body, double h, const double (&w)[4]);
  /// The CG over the free vertices in T (float: half the memory traffic; double for tolerances
  /// float cannot reach), from the warm start. Reads rhs_, st.diagonal, blocks_ (block_rows)
  /// and contacts_; returns the solution (4 lanes per row) in fbuf_ or dv_.
  template <class T>
  const T* solve(System& st, const std::vector<glm::dvec3>& warm, bool warm_start,
                 int max_iterations, double rel_tol2, double abs_tol2, StepStats& stats);
  /// Empty when the state is fine, else the reason. elastic_after: the end state's elastic
  /// energy (end_pass), used when energy_check is set.
  /// With `only`, the sweep covers those vertices (a region's rows) instead of all.
  std::string check(const SoftBody& body, const IntegratorOptions& options, double energy_before,
                    bool energy_check, double elastic_after,
                    const std::vector<std::uint32_t>* only = nullptr) const;
  /// The contacts on sys's rows: their k n n^T blocks (contacts_) and their
  /// h^2 H v term taken off rhs_.
  void gather_contacts(const System& sys, const SoftBody& body, double h2,
                       std::vector<double>* step_residual, const Structure& st);
  // ---- Multirate (integrator_multirate.cpp) ----
  /// One step with IntegratorOptions::far_field_interval > 1 (see there); nothing (and nothing
  /// done) when the body has kinematic vertices.
  std::optional<StepStats> step_multirate(SoftBody& body, Structure& st,
                                          const IntegratorOptions& options,
                                          std::vector<SimEvent>& events, std::uint32_t body_index,
                                          std::uint64_t step_index);
  /// The aggregates' neighbours and the volume groups for st.full (again when it was rebuilt).
  static void make_multirate(Structure& st, const SoftBody& body);
  /// The near region for this tick's loads (SoftBody::loaded_vertices).
  void update_near(Structure& st, const SoftBody& body, const IntegratorOptions& options);
  /// Makes region's system and lists over the aggregates with flags[a] set.
  void build_region(Structure& st, const SoftBody& body, Structure::Region& region,
                    const std::vector<std::uint8_t>& flags);
  /// A step of length h over the region with the guard (rollback, smaller substeps); false
  /// when the body froze.
  bool solve_region(SoftBody& body, Structure& st, Structure::Region& region,
                    const IntegratorOptions& options, double h, StepStats& stats,
                    std::vector<SimEvent>& events, std::uint32_t body_index,
                    std::uint64_t step_index);
  /// One backward Euler substep of length h over the region; energy_out as in substep().
  void region_substep(SoftBody& body, Structure& st, Structure::Region& region,
                      const IntegratorOptions& options, double h, StepStats& stats,
                      double* energy_out);
  /// The region's elastic energy at the current state: its springs and the volume term.
  double region_elastic(const Structure& st, const Structure::Region& region,
                        const SoftBody& body) const;
  // ---- Multirate far field (integrator_far_field.cpp) ----
  /// Makes st's far field follow body: a new copy for another topology or set of constraints,
  /// the copy's state rewritten after edits from outside (untouched false), a freeze or other
  /// options. True when it did any of these: a new period starts.
  static bool far_follow(Structure& st, const SoftBody& body, const IntegratorOptions& options,
                         bool untouched);
  /// A new copy of body for st's far field, its solver prepared (a job part-way in the old
  /// one is run to its end first).
  static void far_reset(Structure& st, const SoftBody& body, const IntegratorOptions& options);
  /// The copy takes body's state (after edits from outside); a job part-way is ended, its
  /// result dropped.
  static void far_sync(FarField& ff, const SoftBody& body);
  /// Runs the job part-way to its end.
  static void finish_far_job(FarField& ff);
  /// At a period's start: the last job's events reported and its result kept for the steps
  /// that apply it; false when it froze (the body is frozen then).
  bool far_finish(Structure& st, SoftBody& body, StepStats& stats, std::vector<SimEvent>& events,
                  std::uint32_t body_index, std::uint64_t step_index);
  /// At a period's start: the copy takes the near aggregates' state and body's loads, and the
  /// next job starts (it first keeps the last result aside, in the pending state).
  static void far_start(Structure& st, const SoftBody& body, std::uint64_t step_index);
  /// The last result into the far vertices of this phase's block of aggregates (phases
  /// 1 .. N - 1 apply one each), and into those that joined the near region since (before
  /// their first near solve); the volume groups they move are summed again. Returns the
  /// vertices moved.
  static std::uint32_t far_apply(Structure& st, SoftBody& body, std::size_t phase,
                                 std::size_t interval);
  /// Writes the last result for aggregate a's rows into body (from the copy itself, or from the
  /// state the job kept aside) and lists the triangles and groups that moved with them.
  static std::uint32_t far_apply_aggregate(Structure& st, SoftBody& body, std::uint32_t a,
                                           bool from_copy);
  /// Runs the job for this step's share of its estimated time, or until step_start + budget_s
  /// if that is later (at the period's last step, to its end).
  static void far_slice(FarField& ff, std::size_t phase, std::size_t interval,
                        std::chrono::steady_clock::time_point step_start, double budget_s);

  std::vector<Structure> structures_;
  std::uint64_t systems_updated_ = 0;
  std::vector<glm::dvec3> saved_x_, saved_v_;
  std::vector<glm::dvec3> f_, grad_;  ///< per vertex: spring forces, volume gradient (x 6)
  /// The thread team (options.threads > 1), and the spring forces and volume gradients of its
  /// members 1..n-1.
  std::shared_ptr<StepThreads> team_;
  StepThreads* step_team_ = nullptr;  ///< the team of the step in progress
  /// The members of the step's team (1 without one).
  [[nodiscard]] unsigned members() const;
  /// The members with force arrays of their own (1 for a sequential team, whose parts share).
  [[nodiscard]] unsigned array_members() const;
  /// Between two long pieces of a step that are not team parts: a sequential team's hook (the
  /// multirate far field's solver may suspend there).
  void checkpoint() const;
  std::vector<std::vector<glm::dvec3>> f_parts_, grad_parts_;
  std::vector<std::uint32_t> row_parts_;  ///< first row of each member's part of the product
  /// The team for options.threads (created or resized here); nullptr for one thread.
  StepThreads* team(const IntegratorOptions& options);
  std::vector<std::uint8_t> free_, mask_;
  /// Multirate: the velocities a region's spring pass reads (the rows', zero elsewhere).
  std::vector<glm::dvec3> held_v_;
  std::vector<std::uint32_t> loaded_;  ///< vertices with an external force this step
  double p6_ = 0.0;                    ///< the last substep's pressure factor
  // Solver data over the free vertices, four lanes (x, y, z, zero pad) per vertex: the
  // right-hand side and the double solve's solution.
  std::vector<double> rhs_, dv_;
  /// Per free vertex, summed per aggregate for sleeping: the squared residual force, pressure
  /// gradient and stopping force of the last substep.
  std::vector<double> row_residual_, row_gradient_, row_speed_;
  std::vector<float> fbuf_;       ///< float CG vectors (r, p, ap and copies of the above)
  std::vector<double> dbuf_;      ///< double CG vectors
  std::vector<float> cbuf_f_;     ///< coarse vectors (rc, xc) of the float solve
  std::vector<double> cbuf_d_;    ///< and of the double solve
  std::vector<double> contacts_;  ///< 5 per contact: compact index, nx, ny, nz, h^2 k
  /// The spring pass's blocks (4 floats per active spring), and the solve's matrix made from
  /// them (block_rows).
  std::vector<float> blocks_, entry_blocks_, jinv_f_;
  bool bound_hessian_ = false;  ///< the step's IntegratorOptions::spring_hessian is Bound
  std::vector<double> held_blocks_, jinv_, diag_blocks_;
};

}  // namespace bisturi::sim
