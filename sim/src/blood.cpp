// Blood as position-based fluid particles (see blood.h).

#include "bisturi/sim/blood.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <type_traits>

#include <glm/geometric.hpp>
#include <glm/gtx/norm.hpp>

#include "step_threads.h"

namespace bisturi::sim {

namespace {

constexpr double kPi = 3.141592653589793;

bool finite(const glm::dvec3& v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}

bool usable(const BloodSource& s) {
  return finite(s.point_m) && finite(s.direction) && glm::length2(s.direction) > 1e-24;
}

/// Mueller, Charypar and Gross 2003: poly6 for densities, the spiky kernel's gradient for
/// pressure (it does not vanish as particles close in); their constants for a kernel radius h.
struct Kernels {
  double h = 0.0, h2 = 0.0, poly6_scale = 0.0, spiky_scale = 0.0;
  explicit Kernels(double radius)
      : h(radius),
        h2(radius * radius),
        poly6_scale(315.0 / (64.0 * kPi * std::pow(radius, 9))),
        spiky_scale(-45.0 / (kPi * std::pow(radius, 6))) {}
  [[nodiscard]] double poly6(double r2) const {
    if (r2 >= h2) return 0.0;
    const double d = h2 - r2;
    return poly6_scale * d * d * d;
  }
  [[nodiscard]] glm::dvec3 spiky_gradient(const glm::dvec3& r) const {
    return spiky_gradient(r, glm::dot(r, r));
  }
  /// The same with r's squared length known.
  [[nodiscard]] glm::dvec3 spiky_gradient(const glm::dvec3& r, double r2) const {
    if (r2 >= h2) return glm::dvec3(0.0);
    const double len = std::sqrt(r2);
    if (len <= 1e-12) return glm::dvec3(0.0);
    const double d = h - len;
    return (spiky_scale * d * d / len) * r;
  }
};

std::int64_t cell_of(double x, double h) {
  return static_cast<std::int64_t>(std::floor(x / h));
}

std::uint64_t cell_key(std::int64_t x, std::int64_t y, std::int64_t z) {
  constexpr std::int64_t kBias = 1 << 20;
  const auto u = [](std::int64_t v) { return static_cast<std::uint64_t>(v + kBias) & 0x1FFFFFu; };
  return u(x) << 42 | u(y) << 21 | u(z);
}

/// Calls visit(first, last) for the entries [first, last) of `cells` (sorted by key) in each
/// column of the 27 cells round the one holding a point: the three cells along z are neighbours
/// in key order, so one run a column. The points must come in the order of their cells' keys:
/// each column's start then only moves on, and a cursor per column walks the entries once
/// instead of a search per cell.
class NearCells {
 public:
  NearCells(const std::vector<std::pair<std::uint64_t, std::uint32_t>>& cells, double h)
      : cells_(cells), h_(h) {}

  template <class Visit>
  void visit_columns(const glm::dvec3& at, Visit&& visit) {
    const std::int64_t cx = cell_of(at.x, h_), cy = cell_of(at.y, h_), cz = cell_of(at.z, h_);
    std::size_t column = 0;
    for (std::int64_t dx = -1; dx <= 1; ++dx)
      for (std::int64_t dy = -1; dy <= 1; ++dy, ++column) {
        const std::uint64_t low = cell_key(cx + dx, cy + dy, cz - 1);
        std::size_t& b = cursor_[column];
        while (b < cells_.size() && cells_[b].first < low)
          ++b;
        std::size_t e = b;
        while (e < cells_.size() && cells_[e].first <= low + 2)
          ++e;
        if (e > b) visit(b, e);
      }
  }

 private:
  const std::vector<std::pair<std::uint64_t, std::uint32_t>>& cells_;
  double h_;
  std::array<std::size_t, 9> cursor_{};
};

/// Entry i of the parts' arrays summed, in part order: the same bits whichever thread filled
/// which part.
template <class T, std::size_t N>
T sum_of_parts(const std::array<std::vector<T>, N>& parts, std::size_t i) {
  T sum = parts[0][i];
  for (std::size_t t = 1; t < N; ++t)
    sum = sum + parts[t][i];
  return sum;
}

}  // namespace

Blood::~Blood() = default;
Blood::Blood(Blood&&) noexcept = default;
Blood& Blood::operator=(Blood&&) noexcept = default;

Blood::Blood(const BloodOptions& options) : options_(options) {
  // A helper may share a core with the calling thread (the blood runs on what the session
  // leaves free): it spins only briefly for the next part before it sleeps. One thread runs
  // the parts in turn.
  constexpr unsigned kHelperSpins = 200;
  team_ = options_.threads > 1
              ? std::make_unique<StepThreads>(kParts, kHelperSpins, options_.helper_start)
              : std::make_unique<StepThreads>(kParts, [] {});
  const double spacing = 2.0 * options_.particle_radius_m;
  h_ = 2.0 * spacing;
  const Kernels kernels(h_);
  particle_volume_m3_ = spacing * spacing * spacing;
  mass_kg_ = options_.density_kg_per_m3 * particle_volume_m3_;
  // The rest density the constraint holds is the density a particle has in a cubic lattice at
  // the rest spacing (the kernel's sum there), so blood at rest packing is at rest.
  double sum = 0.0;
  std::vector<glm::dvec3> lattice;
  for (int i = -2; i <= 2; ++i)
    for (int j = -2; j <= 2; ++j)
      for (int k = -2; k <= 2; ++k) {
        sum += kernels.poly6(spacing * spacing * (i * i + j * j + k * k));
        if (i != 0 || j != 0 || k != 0) lattice.push_back(spacing * glm::dvec3(i, j, k));
      }
  rest_density_ = mass_kg_ * sum;
  // The constraint's softening: a tenth of its gradient's weight at rest packing, so a particle
  // with few neighbours is not thrown about (Macklin and Mueller's relaxation parameter).
  double grad_sum = 0.0;
  for (const glm::dvec3& r : lattice)
    grad_sum += glm::length2(mass_kg_ / rest_density_ * kernels.spiky_gradient(r));
  relaxation_ = 0.1 * grad_sum;
}

std::size_t Blood::emit(std::span<const BloodSource> sources, double flow_m3_s, double speed_m_s,
                        double dt_s) {
  if (sources.empty() || !(flow_m3_s > 0.0)) return 0;
  pending_m3_ += flow_m3_s * dt_s;
  if (options_.recycle) {
    const auto wanted = static_cast<std::size_t>(pending_m3_ / particle_volume_m3_);
    const std::size_t room =
        options_.max_particles > x_.size() ? options_.max_particles - x_.size() : 0;
    if (wanted > room) recycle_pooled(wanted - room);
  }
  std::size_t made = 0;
  while (pending_m3_ >= particle_volume_m3_ && x_.size() < options_.max_particles) {
    // A source with no place or no direction (an opening cut down to nothing) emits nothing: its
    // particles would be no numbers, and would stop the neighbour search.
    std::size_t tried = 0;
    while (tried < sources.size() && !usable(sources[next_source_ % sources.size()])) {
      ++next_source_;
      ++tried;
    }
    if (tried == sources.size()) {
      pending_m3_ = 0.0;
      break;
    }
    pending_m3_ -= particle_volume_m3_;
    const BloodSource& s = sources[next_source_ % sources.size()];
    // Spread over the opening by the golden angle, so particles never start on one another.
    const glm::dvec3 d = glm::normalize(s.direction);
    const glm::dvec3 a = glm::normalize(
        glm::cross(d, std::abs(d.z) < 0.9 ? glm::dvec3(0, 0, 1) : glm::dvec3(1, 0, 0)));
    const glm::dvec3 b = glm::cross(d, a);
    const double angle = 2.399963229728653 * static_cast<double>(counts_.emitted);
    const double ring =
        options_.particle_radius_m * std::sqrt(static_cast<double>(counts_.emitted % 7));
    x_.push_back(s.point_m + options_.particle_radius_m * d +
                 ring * (std::cos(angle) * a + std::sin(angle) * b));
    v_.push_back(speed_m_s * d);
    pooled_.push_back(0);
    resting_.push_back(0);
    touching_.push_back(0);
    serial_.push_back(counts_.emitted);
    ++next_source_;
    ++counts_.emitted;
    ++made;
  }
  // Past the limit the flow is not held back for later: it would all come at once.
  if (x_.size() >= options_.max_particles) pending_m3_ = 0.0;
  return made;
}

template <class T>
void Blood::permute(std::vector<T>& values) {
  static_assert(std::is_trivially_copyable_v<T>);
  permuted_.resize(values.size() * sizeof(T));
  for (std::size_t a = 0; a < values.size(); ++a)
    std::memcpy(permuted_.data() + a * sizeof(T), &values[reorder_[a]], sizeof(T));
  std::memcpy(values.data(), permuted_.data(), permuted_.size());
}

void Blood::find_neighbours() {
  const std::size_t n = x_.size();
  cells_.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    cells_[i] = {cell_key(cell_of(p_[i].x, h_), cell_of(p_[i].y, h_), cell_of(p_[i].z, h_)),
                 static_cast<std::uint32_t>(i)};
  std::sort(cells_.begin(), cells_.end());
  // The particles themselves in cell order: neighbours then lie close in memory, and every pass
  // over the pairs below reads and writes its particles' entries nearly in a row.
  reorder_.resize(n);
  for (std::size_t a = 0; a < n; ++a) {
    reorder_[a] = cells_[a].second;
    cells_[a].second = static_cast<std::uint32_t>(a);
  }
  permute(x_);
  permute(v_);
  permute(p_);
  permute(pooled_);
  permute(resting_);
  permute(touching_);
  permute(serial_);
  // The pairs with a particle in flight, in the order the cells were searched: fixed by the
  // positions, so the sums come out the same bits every run.
  pairs_.clear();
  list_neighbours();
}

void Blood::list_neighbours() {
  const std::size_t n = cells_.size();
  const double h2 = h_ * h_;
  // The particles are in cell order (find_neighbours): a cell's entries are its particles.
  NearCells near(cells_, h_);  // the cells in key order: begin only grows
  // Cell by cell: the cells around each are looked up once for all its particles in flight.
  for (std::size_t begin = 0; begin < n;) {
    std::size_t end = begin;
    here_.clear();  // the cell's particles in flight, ascending
    for (; end < n && cells_[end].first == cells_[begin].first; ++end)
      if (!pooled_[end]) here_.push_back(static_cast<std::uint32_t>(end));
    const std::size_t count = here_.size();
    if (count > 0) {
      // A pair of particles both in flight is found once, from the earlier of the two. Each
      // candidate is written and kept by moving past it when within reach, without a branch:
      // which candidates are within reach is as good as random to the branch predictor.
      near.visit_columns(p_[begin], [&](std::size_t first, std::size_t last) {
        std::size_t kept = pairs_.size();
        pairs_.resize(kept + count * (last - first));  // room for all, not initialised
        NeighbourPair* out = pairs_.data();
        for (std::size_t b = first; b < last; ++b) {
          const auto j = static_cast<std::uint32_t>(b);
          const bool both = pooled_[j] == 0;
          const glm::dvec3 q = p_[b];
          // here_ ascends: past the first at or after b, a pair both in flight is found from b.
          for (std::size_t k = 0; k < count && !(both && b <= here_[k]); ++k) {
            out[kept] = NeighbourPair(here_[k], j);
            kept += glm::length2(p_[here_[k]] - q) < h2 ? 1 : 0;
          }
        }
        pairs_.resize(kept);
      });
    }
    begin = end;
  }
}

void Blood::solve_density() {
  const Kernels kernels(h_);
  const std::size_t n = x_.size();
  const std::size_t pairs = pairs_.size();
  const double scale = mass_kg_ / rest_density_;
  gradient_.resize(pairs);
  for (unsigned t = 0; t < kParts; ++t) {
    sums_[t].resize(n);
    delta_[t].resize(n);
  }
  lambda_.resize(n);
  team_->run([&](unsigned t) {
    std::vector<DensitySums>& sums = sums_[t];
    // Each particle's own kernel value once, in the first part's sums.
    std::fill(sums.begin(), sums.end(),
              DensitySums{glm::dvec3(0.0), t == 0 ? mass_kg_ * kernels.poly6(0.0) : 0.0, 0.0});
    const Range r = part_of(pairs, kParts, t);
    for (std::size_t k = r.begin; k < r.end; ++k) {
      const auto [i, j] = pairs_[k];
      const glm::dvec3 r_ij = p_[i] - p_[j];
      const double r2 = glm::dot(r_ij, r_ij);
      gradient_[k] = glm::dvec3(0.0);  // the position update below uses it again
      if (r2 >= kernels.h2) continue;  // beyond the kernel: one distance
      const double w = mass_kg_ * kernels.poly6(r2);
      sums[i].density += w;
      sums[j].density += w;
      gradient_[k] = kernels.spiky_gradient(r_ij, r2);
      const glm::dvec3 g = scale * gradient_[k];
      const double g2 = glm::dot(g, g);
      sums[i].gradient += g;
      sums[i].gradient_squares += g2;
      sums[j].gradient -= g;
      sums[j].gradient_squares += g2;
    }
  });
  team_->run([&](unsigned t) {
    const Range r = part_of(n, kParts, t);
    for (std::size_t i = r.begin; i < r.end; ++i) {
      const DensitySums s = sum_of_parts(sums_, i);
      // Only compression is corrected: a free surface (too few neighbours) is not pulled in.
      // Pooled blood is a boundary (Akinci et al. 2012, "Versatile rigid-fluid coupling for
      // incompressible SPH"): it adds to the density of the blood in flight beside it and holds
      // no constraint of its own, so its pairs with other pooled particles are never listed.
      const double c = std::max(0.0, s.density / rest_density_ - 1.0);
      lambda_[i] =
          pooled_[i] ? 0.0 : -c / (s.gradient_squares + glm::length2(s.gradient) + relaxation_);
    }
  });
  team_->run([&](unsigned t) {
    std::vector<glm::dvec3>& delta = delta_[t];
    std::fill(delta.begin(), delta.end(), glm::dvec3(0.0));
    const Range r = part_of(pairs, kParts, t);
    for (std::size_t k = r.begin; k < r.end; ++k) {
      const auto [i, j] = pairs_[k];
      const glm::dvec3 d = (lambda_[i] + lambda_[j]) * gradient_[k];
      delta[i] += d;
      delta[j] -= d;
    }
  });
  // Only particles in flight move.
  team_->run([&](unsigned t) {
    const Range r = part_of(n, kParts, t);
    for (std::size_t i = r.begin; i < r.end; ++i)
      if (!pooled_[i]) p_[i] += scale * sum_of_parts(delta_, i);
  });
}

void Blood::collide(std::span<const BloodSurface> surfaces, bool pooled_too) {
  team_->run([&](unsigned t) {
    const Range part = part_of(x_.size(), kParts, t);
    collide(surfaces, pooled_too, part.begin, part.end);
  });
}

void Blood::collide(std::span<const BloodSurface> surfaces, bool pooled_too, std::size_t begin,
                    std::size_t end) {
  const double r = options_.particle_radius_m;
  constexpr double kMaxDepth_m = 0.006;  // deeper: the far side of a thin part, not this one
  for (std::size_t i = begin; i < end; ++i) {
    if (pooled_[i] && !pooled_too) continue;
    touching_[i] = 0;
    for (const BloodSurface& s : surfaces) {
      const auto [lo, hi] = s.bvh->bounds();
      if (glm::any(glm::lessThan(p_[i], lo - glm::dvec3(r))) ||
          glm::any(glm::greaterThan(p_[i], hi + glm::dvec3(r))))
        continue;
      const SurfacePoint q = s.bvh->closest_point(*s.body, p_[i], kMaxDepth_m);
      if (!q.found) continue;
      const double along = glm::dot(p_[i] - q.point_m, q.normal);  // < 0: inside the tissue
      if (along >= r) continue;
      // Out to the surface plus the particle's radius; a pooled particle the tissue moved into
      // is freed and pushed out the same way.
      p_[i] += (r - along) * q.normal;
      touching_[i] = 1;
      pooled_[i] = 0;
    }
    if (p_[i].z < options_.floor_z_m + r) {  // the tray
      p_[i].z = options_.floor_z_m + r;
      touching_[i] = 1;
    }
  }
}

void Blood::remove_drained() {
  remove_.assign(x_.size(), 0);
  for (std::size_t i = 0; i < x_.size(); ++i) {
    const glm::dvec3& x = x_[i];
    // A particle whose position or velocity is no number drains as well.
    const bool inside = x.x >= options_.field_min_m.x && x.y >= options_.field_min_m.y &&
                        x.x <= options_.field_max_m.x && x.y <= options_.field_max_m.y &&
                        finite(x) && finite(v_[i]);
    if (!inside) {
      remove_[i] = 1;
      ++counts_.drained;
    }
  }
  remove_marked();
}

void Blood::recycle_pooled(std::size_t count) {
  remove_.assign(x_.size(), 0);
  // The oldest: the smallest serials (the particles are kept in cell order, not emission order).
  oldest_.clear();
  for (std::size_t i = 0; i < x_.size(); ++i)
    if (pooled_[i]) oldest_.emplace_back(serial_[i], static_cast<std::uint32_t>(i));
  count = std::min(count, oldest_.size());
  std::nth_element(oldest_.begin(), oldest_.begin() + static_cast<std::ptrdiff_t>(count),
                   oldest_.end());
  for (std::size_t k = 0; k < count; ++k) {
    remove_[oldest_[k].second] = 1;
    ++counts_.recycled;
  }
  remove_marked();
  counts_.pooled = static_cast<std::uint64_t>(std::count(pooled_.begin(), pooled_.end(), 1));
  counts_.in_flight = x_.size() - counts_.pooled;
}

void Blood::remove_marked() {
  std::size_t w = 0;
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (remove_[i]) continue;
    x_[w] = x_[i];
    v_[w] = v_[i];
    pooled_[w] = pooled_[i];
    resting_[w] = resting_[i];
    touching_[w] = touching_[i];
    serial_[w] = serial_[i];
    ++w;
  }
  x_.resize(w);
  v_.resize(w);
  pooled_.resize(w);
  resting_.resize(w);
  touching_.resize(w);
  serial_.resize(w);
}

void Blood::step(double dt_s, std::span<const BloodSurface> surfaces) {
  const int substeps = std::max(1, options_.substeps);
  const double h = dt_s / substeps;
  for (int s = 0; s < substeps && !x_.empty(); ++s) {
    const std::size_t n = x_.size();
    p_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      if (!pooled_[i]) v_[i] += h * options_.gravity_m_s2;
      p_[i] = pooled_[i] ? x_[i] : x_[i] + h * v_[i];
    }
    find_neighbours();
    for (int it = 0; it < options_.iterations; ++it)
      solve_density();
    // The surfaces stand still within a step, and pooled blood does: once a step is enough.
    collide(surfaces, s == 0);
    for (std::size_t i = 0; i < n; ++i) {
      v_[i] = pooled_[i] ? glm::dvec3(0.0) : (p_[i] - x_[i]) / h;
      if (touching_[i]) {
        // Friction on the surface: the tangential part of the motion slows.
        v_[i] *= 1.0 - options_.surface_friction;
      }
    }
    // XSPH: each particle's velocity drawn towards its neighbours' (the blood's viscosity).
    const Kernels kernels(h_);
    for (unsigned t = 0; t < kParts; ++t) {
      delta_[t].resize(n);
      weight_[t].resize(n);
    }
    team_->run([&](unsigned t) {
      std::vector<glm::dvec3>& delta = delta_[t];
      std::vector<double>& weight = weight_[t];
      std::fill(delta.begin(), delta.end(), glm::dvec3(0.0));
      std::fill(weight.begin(), weight.end(), 0.0);
      const Range r = part_of(pairs_.size(), kParts, t);
      for (std::size_t k = r.begin; k < r.end; ++k) {
        const auto [i, j] = pairs_[k];
        const double w = kernels.poly6(glm::length2(p_[i] - p_[j]));
        const glm::dvec3 dv = w * (v_[j] - v_[i]);
        delta[i] += dv;
        delta[j] -= dv;
        weight[i] += w;
        weight[j] += w;
      }
    });
    for (std::size_t i = 0; i < n; ++i) {
      if (pooled_[i]) continue;  // at rest: its velocity stays zero
      const double weight = sum_of_parts(weight_, i);
      if (weight > 0.0) v_[i] += options_.viscosity * sum_of_parts(delta_, i) / weight;
      x_[i] = p_[i];
      // Come to rest on a surface: pooled (still a neighbour of the others, never moved again
      // unless the tissue pushes it).
      resting_[i] = touching_[i] && glm::length(v_[i]) < options_.pool_speed_m_s
                        ? static_cast<std::uint16_t>(resting_[i] + 1)
                        : 0;
      if (resting_[i] >= options_.pool_steps) {
        pooled_[i] = 1;
        v_[i] = glm::dvec3(0.0);
      }
    }
    remove_drained();
  }
  counts_.pooled = static_cast<std::uint64_t>(std::count(pooled_.begin(), pooled_.end(), 1));
  counts_.in_flight = x_.size() - counts_.pooled;
}

}  // namespace bisturi::sim
