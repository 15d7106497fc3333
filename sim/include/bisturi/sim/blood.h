#pragma once
// Blood from a cut vessel: position-based fluid particles (Macklin and Mueller, "Position Based
// Fluids", 2013: a density constraint per particle solved by a few Jacobi iterations, XSPH
// viscosity) with the SPH kernels of Mueller, Charypar and Gross 2003. Particles leave the
// openings at the flow each is given, collide with the tissue's surfaces (their BVHs) and the
// tray under the field, run down them and pool where they come to rest; those that leave the
// field across drain. Every particle is counted: emitted = in flight + pooled + drained.
// Deterministic (fixed order; its work in fixed parts, whichever threads run them), so a replay
// of the same steps bleeds the same.

#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

class StepThreads;

struct BloodOptions {
  double particle_radius_m = 0.0012;  ///< half the particles' rest spacing
  double density_kg_per_m3 = 1060.0;
  /// XSPH velocity smoothing (0-1): blood's viscosity at this resolution.
  double viscosity = 0.1;
  int iterations = 3;                ///< density constraint iterations per substep
  int substeps = 2;                  ///< per step
  std::size_t max_particles = 5000;  ///< at most this many in flight and pooled
  /// At max_particles the oldest pooled particles make room for new ones (soaked up, as a swab
  /// would): the vessel goes on bleeding at a bounded cost. Off: emission stops there.
  bool recycle = true;
  glm::dvec3 gravity_m_s2{0.0, 0.0, -9.81};
  /// The tray under the field (the table's drapes): a plane at this height the blood runs on and
  /// pools on like any surface.
  double floor_z_m = -1.0;
  /// The field's extent across (x, y): a particle that leaves it drains (off the table).
  glm::dvec3 field_min_m{-1.0, -1.0, 0.0}, field_max_m{1.0, 1.0, 0.0};
  double pool_speed_m_s = 0.01;  ///< slower than this on a surface for pool_steps: pooled
  int pool_steps = 30;
  double surface_friction = 0.5;  ///< the tangential speed kept per contact is 1 - this
  /// Threads that step the blood (the calling one and helpers). The work over the particles and
  /// their pairs is cut into the same two parts whatever the count, each summed on its own, so
  /// the blood comes out the same bits with one thread or two.
  unsigned threads = 1;
  /// Called first on each helper's own thread (a scheduling policy, say).
  std::function<void()> helper_start;
};

/// Where blood leaves a vessel: a point of the opening and the direction out of the lumen.
struct BloodSource {
  glm::dvec3 point_m{0.0};
  glm::dvec3 direction{0.0, 0.0, 1.0};
};

/// A tissue surface the blood runs on.
struct BloodSurface {
  const SoftBody* body = nullptr;
  const SurfaceBvh* bvh = nullptr;
};

struct BloodCounts {
  std::uint64_t emitted = 0;
  std::uint64_t in_flight = 0;
  std::uint64_t pooled = 0;
  std::uint64_t drained = 0;
  std::uint64_t recycled = 0;  ///< pooled particles taken to make room (BloodOptions::recycle)
};

class Blood {
 public:
  explicit Blood(const BloodOptions& options = {});
  ~Blood();
  Blood(Blood&&) noexcept;
  Blood& operator=(Blood&&) noexcept;

  /// Emits the volume `flow_m3_s` * dt_s (with what earlier calls left over) from `sources` in
  /// turn, each particle at `speed_m_s` along its source's direction; returns how many.
  std::size_t emit(std::span<const BloodSource> sources, double flow_m3_s, double speed_m_s,
                   double dt_s);
  /// Advances the particles by dt_s against the surfaces.
  void step(double dt_s, std::span<const BloodSurface> surfaces);

  [[nodiscard]] const BloodCounts& counts() const { return counts_; }
  /// Volume of one particle (m^3): the flow's unit.
  [[nodiscard]] double particle_volume_m3() const { return particle_volume_m3_; }
  /// Blood that left the vessels so far (ml).
  [[nodiscard]] double emitted_ml() const {
    return static_cast<double>(counts_.emitted) * particle_volume_m3_ * 1e6;
  }
  /// The particles in the field (in flight and pooled), for drawing.
  [[nodiscard]] const std::vector<glm::dvec3>& positions() const { return x_; }
  [[nodiscard]] bool pooled(std::size_t i) const { return pooled_[i] != 0; }
  [[nodiscard]] const BloodOptions& options() const { return options_; }

 private:
  /// The neighbour pairs the step needs: those with a particle in flight (a pool that nothing
  /// flows over does not change, and costs nothing).
  void find_neighbours();
  /// Lists the pairs of the particles in flight with their neighbours, each pair once.
  void list_neighbours();
  void solve_density();
  /// Pushes the particles in flight, and the pooled ones if `pooled_too`, out of the surfaces.
  void collide(std::span<const BloodSurface> surfaces, bool pooled_too);
  /// The same for the particles [begin, end).
  void collide(std::span<const BloodSurface> surfaces, bool pooled_too, std::size_t begin,
               std::size_t end);
  void remove_drained();
  /// Takes the `count` oldest pooled particles (the first emitted).
  void recycle_pooled(std::size_t count);
  /// Removes the particles whose remove_ is set, keeping the others' order.
  void remove_marked();

  BloodOptions options_;
  double h_ = 0.0;             ///< kernel radius
  double rest_density_ = 0.0;  ///< the kernel's density at rest spacing (kg/m^3)
  double relaxation_ = 0.0;    ///< the constraint's softening (Macklin and Mueller's epsilon)
  double particle_volume_m3_ = 0.0;
  double mass_kg_ = 0.0;
  double pending_m3_ = 0.0;  ///< flow not yet a whole particle
  std::size_t next_source_ = 0;
  BloodCounts counts_;
  std::vector<glm::dvec3> x_, v_, p_;  ///< positions, velocities, predicted positions
  std::vector<std::uint8_t> pooled_;
  std::vector<std::uint16_t> resting_;  ///< steps spent slow on a surface
  std::vector<std::uint8_t> touching_;  ///< on a surface after the last collision pass
  /// Each particle's place in emission order (the particles are kept in the order of their
  /// cells, so neighbours lie close in memory).
  std::vector<std::uint64_t> serial_;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> oldest_;  ///< scratch: recycle_pooled
  /// Neighbours: each pair of particles within the kernel's reach once (its kernel values are
  /// symmetric, its gradients opposite, so each is computed once for both).
  struct NeighbourPair {
    std::uint32_t i, j;
    // Left uninitialised by default: the neighbour search sizes the list for every candidate
    // and keeps those within reach.
    // NOLINTNEXTLINE(cppcoreguidelines-pro-type-member-init, modernize-use-equals-default)
    NeighbourPair() {}
    NeighbourPair(std::uint32_t a, std::uint32_t b) : i(a), j(b) {}
  };
  std::vector<NeighbourPair> pairs_;
  /// Per particle, this iteration: the density and the constraint gradient's sums.
  struct DensitySums {
    glm::dvec3 gradient{0.0};
    double density = 0.0;
    double gradient_squares = 0.0;
    DensitySums operator+(const DensitySums& o) const {
      return {gradient + o.gradient, density + o.density, gradient_squares + o.gradient_squares};
    }
  };
  /// The work over pairs and particles goes in kParts parts, each pair's sums into its part's
  /// arrays, added in part order: the same bits whichever thread runs which part.
  static constexpr unsigned kParts = 2;
  std::unique_ptr<StepThreads> team_;
  std::array<std::vector<DensitySums>, kParts> sums_;
  std::vector<double> lambda_;
  std::array<std::vector<glm::dvec3>, kParts> delta_;
  std::array<std::vector<double>, kParts> weight_;              ///< scratch: XSPH's kernel weights
  std::vector<std::pair<std::uint64_t, std::uint32_t>> cells_;  ///< scratch
  std::vector<std::uint32_t> reorder_;   ///< scratch: the particles' former indices in cell order
  std::vector<std::uint32_t> here_;      ///< scratch: list_neighbours' particles of one cell
  std::vector<unsigned char> permuted_;  ///< scratch for permute()
  /// Puts a per-particle array in reorder_'s order.
  template <class T>
  void permute(std::vector<T>& values);
  /// Scratch: the spiky kernel's gradient for each pair (as pairs_), this iteration.
  std::vector<glm::dvec3> gradient_;
  std::vector<std::uint8_t> remove_;  ///< scratch
};

}  // namespace bisturi::sim
