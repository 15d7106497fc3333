#include "bisturi/sim/volume/elastic_volume.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>

#include <glm/geometric.hpp>
#include <glm/gtx/norm.hpp>
#include <glm/matrix.hpp>

#include "block_matrix.h"
#include "hex_element.h"

namespace bisturi::sim {

struct ElasticVolume::Solver {
  explicit Solver(const HexLattice& lattice)
      : force(lattice.rest.size()), step(lattice.rest.size()) {}
  /// The step's matrix, its structure built on first use: a volume that only gives forces (the
  /// refined lattice a cut passes through on its way to the separated one) never builds it.
  BlockMatrix& matrix(const HexLattice& lattice) {
    if (!built) built.emplace(lattice.rest.size(), lattice.cells);
    return *built;
  }
  std::optional<BlockMatrix> built;
  std::vector<glm::dvec3> force;
  std::vector<glm::dvec3> step;
  std::vector<glm::dvec3> start;
  std::vector<glm::dvec3> product;       ///< (h tau + h^2) K v in a dynamic step
  std::vector<glm::dvec3> held_step;     ///< the held nodes' given dv (zero elsewhere)
  std::vector<glm::dvec3> held_product;  ///< the matrix times held_step
  std::vector<glm::dvec3> unit_load;     ///< step_compliance's load
  std::vector<glm::dvec3> give;          ///< and its solution (the warm start of the next)
  /// Element stiffness at unit fill, one per distinct box shape (a graded lattice has few), and
  /// each cell's shape: computed once, not per assembly.
  std::vector<HexStiffness> shapes;
  std::vector<std::uint32_t> cell_shape;
  /// Per cell: its stiffness R K R^T for the rotation it was last warped with (blocks (a, b),
  /// a <= b, in row order), and that rotation.
  std::vector<std::array<glm::mat3, 36>> warped;
  std::vector<glm::dmat3> warped_rotation;
};

ElasticVolume::ElasticVolume(HexLattice lattice, const ElasticMaterial& material, ElasticLaw law)
    : lattice_(std::move(lattice)), law_(law) {
  check_elastic(material);
  const double e = material.youngs_modulus_kPa * 1e3, nu = material.poisson_ratio;
  youngs_Pa_ = e;
  for (const auto& axis : lattice_.axis)
    for (std::size_t i = 0; i + 1 < axis.size(); ++i)
      finest_cell_m_ = std::min(finest_cell_m_, axis[i + 1] - axis[i]);
  mu_ = e / (2.0 * (1.0 + nu));
  lambda_ = e * nu / ((1.0 + nu) * (1.0 - 2.0 * nu));
  retardation_s_ = material.retardation_time_s;
  x_ = lattice_.rest;
  v_.assign(x_.size(), glm::dvec3(0.0));
  held_.assign(x_.size(), 0);
  hanging_index_.assign(x_.size(), -1);
  for (std::size_t k = 0; k < lattice_.hanging.size(); ++k)
    hanging_index_[lattice_.hanging[k].node] = static_cast<std::int32_t>(k);
  mass_.assign(x_.size(), 0.0);
  solver_ = std::make_unique<Solver>(lattice_);
  Solver& s = *solver_;
  s.product.resize(x_.size());
  std::vector<glm::dvec3> shape_sides;
  s.cell_shape.resize(lattice_.cells.size());
  for (std::size_t c = 0; c < lattice_.cells.size(); ++c) {
    const glm::dvec3 h = lattice_.cell_sides(c);
    const double node_mass = material.density_kg_per_m3 * h.x * h.y * h.z * lattice_.fill[c] / 8.0;
    for (const std::uint32_t node : lattice_.cells[c])
      mass_[node] += node_mass;
    const auto same = std::find(shape_sides.begin(), shape_sides.end(), h);
    s.cell_shape[c] = static_cast<std::uint32_t>(same - shape_sides.begin());
    if (same != shape_sides.end()) continue;
    shape_sides.push_back(h);
    s.shapes.emplace_back();
    box_stiffness(h, mu_, lambda_, 1.0, s.shapes.back());
  }
}

ElasticVolume::~ElasticVolume() = default;
ElasticVolume::ElasticVolume(ElasticVolume&&) noexcept = default;
ElasticVolume& ElasticVolume::operator=(ElasticVolume&&) noexcept = default;

void ElasticVolume::hold(std::uint32_t node) {
  // A hanging node follows its masters: they are held instead.
  if (const std::int32_t k = hanging_index_.at(node); k >= 0) {
    const HangingNode& h = lattice_.hanging[static_cast<std::size_t>(k)];
    for (std::uint32_t m = 0; m < h.masters_count; ++m)
      hold(h.masters[m]);
    return;
  }
  held_.at(node) = 1;
  x_[node] = lattice_.rest[node];
  v_[node] = glm::dvec3(0.0);
}

void ElasticVolume::set_state(std::span<const glm::dvec3> positions,
                              std::span<const glm::dvec3> velocities) {
  if (positions.size() != x_.size() || velocities.size() != v_.size())
    throw std::invalid_argument("ElasticVolume::set_state: sizes differ from the node count");
  std::copy(positions.begin(), positions.end(), x_.begin());
  std::copy(velocities.begin(), velocities.end(), v_.begin());
}

DynamicResult ElasticVolume::advance(std::span<const PointLoad> loads, const DynamicOptions& o) {
  Solver& s = *solver_;
  BlockMatrix& matrix = s.matrix(lattice_);
  const std::size_t n = x_.size();
  const double h = o.dt_s;
  const double kv_weight = h * retardation_s_ + h * h;
  // s.force = f(x), the matrix (h tau + h^2) K.
  assemble_elements(true, o.warp_tolerance, kv_weight);
  matrix.multiply(v_, s.product);
  // The right-hand side before the loads: h (f - tau K v + M g) - h^2 K v (the product is
  // (h tau + h^2) K v: the masses join the matrix after it).
  for (std::size_t i = 0; i < n; ++i)
    s.force[i] = h * (s.force[i] + mass_[i] * o.gravity_m_s2) - s.product[i];
  for (std::size_t i = 0; i < n; ++i)
    matrix.add(matrix.diagonal_slot(i), glm::mat3(static_cast<float>(mass_[i])));
  for (const PointLoad& load : loads) {
    const auto& cell = lattice_.cells[load.point.cell];
    const auto& w = load.point.weights;
    glm::dvec3 point_velocity(0.0);
    for (std::size_t a = 0; a < 8; ++a)
      point_velocity += w[a] * v_[cell[a]];
    const glm::dvec3 rhs = h * load.force_N - (h * h) * (load.stiffness_N_per_m * point_velocity);
    const glm::dmat3 scaled = (h * h) * load.stiffness_N_per_m;
    const auto& slots = matrix.cell_slots(load.point.cell);
    for (std::size_t a = 0; a < 8; ++a) {
      if (w[a] == 0.0) continue;
      s.force[cell[a]] += w[a] * rhs;
      for (std::size_t b = 0; b < 8; ++b)
        matrix.add(slots[a * 8 + b], glm::mat3((w[a] * w[b]) * scaled));
    }
  }
  // Held nodes that move (or stop moving) have a given dv: its coupling to the free nodes goes to
  // the right-hand side, A_ff dv_f = b_f - A_fh dv_h.
  bool held_moves = false;
  for (std::size_t i = 0; i < n && !held_moves; ++i)
    held_moves = held_[i] && v_[i] != held_velocity_;
  if (held_moves) {
    s.held_step.assign(n, glm::dvec3(0.0));
    s.held_product.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      if (held_[i]) s.held_step[i] = held_velocity_ - v_[i];
    BlockMatrix::expand(s.held_step, lattice_.hanging);
    matrix.multiply(s.held_step, s.held_product);
    for (std::size_t i = 0; i < n; ++i)
      s.force[i] -= s.held_product[i];
  }
  // Warm start: the last step's velocity change (the motion changes smoothly step to step).
  if (s.step.size() != n) s.step.assign(n, glm::dvec3(0.0));
  const BlockMatrix::SolveStats cg =
      matrix.solve(s.force, s.step, held_, o.cg_tolerance, o.max_cg, lattice_.hanging);
  if (!lattice_.hanging.empty()) {
    // The hanging nodes follow the held ones at their given change too.
    for (std::size_t i = 0; i < n; ++i)
      if (held_[i]) s.step[i] = held_velocity_ - v_[i];
    BlockMatrix::expand(s.step, lattice_.hanging);
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (held_[i]) {
      v_[i] = held_velocity_;
      x_[i] += h * v_[i];
      continue;
    }
    v_[i] += s.step[i];
    x_[i] += h * v_[i];
  }
  if (!releasing_.empty()) {
    const double kept = std::exp(-h / release_s_);
    for (glm::dvec3& r : releasing_)
      r *= kept;
  }
  return {cg.iterations, cg.relative_residual};
}

double ElasticVolume::step_compliance(std::span<const PointLoad> contact,
                                      const glm::dvec3& direction, double dt_s, double cg_tolerance,
                                      int max_cg) {
  Solver& s = *solver_;
  BlockMatrix& matrix = s.matrix(lattice_);
  const std::size_t n = x_.size();
  double total = 0.0;
  for (const PointLoad& c : contact)
    total += glm::dot(direction, c.stiffness_N_per_m * direction);
  if (!(total > 0.0)) return 0.0;
  s.unit_load.assign(n, glm::dvec3(0.0));
  if (s.give.size() != n) s.give.assign(n, glm::dvec3(0.0));
  for (const PointLoad& c : contact) {
    const double share = glm::dot(direction, c.stiffness_N_per_m * direction) / total;
    const auto& cell = lattice_.cells[c.point.cell];
    for (std::size_t a = 0; a < 8; ++a)
      s.unit_load[cell[a]] += (share * c.point.weights[a]) * direction;
  }
  // The step's matrix as advance() left it: A dv = h f, dx = h dv.
  matrix.solve(s.unit_load, s.give, held_, cg_tolerance, max_cg, lattice_.hanging);
  double along = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    if (!held_[i]) along += glm::dot(s.unit_load[i], s.give[i]);
  return std::max(0.0, dt_s * dt_s * along);
}

glm::dvec3 ElasticVolume::held_offset() const {
  for (std::size_t i = 0; i < held_.size(); ++i)
    if (held_[i]) return x_[i] - lattice_.rest[i];
  return glm::dvec3(0.0);
}

std::size_t ElasticVolume::held_count() const {
  return static_cast<std::size_t>(std::count(held_.begin(), held_.end(), std::uint8_t{1}));
}

PressResult ElasticVolume::press_sphere(std::span<const EmbeddedPoint> points,
                                        const glm::dvec3& centre, double radius,
                                        const PressOptions& o) {
  Solver& s = *solver_;
  BlockMatrix& matrix = s.matrix(lattice_);
  const std::size_t n = x_.size();
  if (multipliers_.size() != points.size()) multipliers_.assign(points.size(), 0.0);
  // The penalty, unless given: twenty times what one finest cell resists with (E h). The
  // multipliers carry the contact force; the penalty sets how fast they get there, and a stiffer
  // one makes the contact set flip between Newton steps.
  const double penalty =
      o.penalty_N_per_m > 0.0 ? o.penalty_N_per_m : 20.0 * youngs_Pa_ * finest_cell_m_;

  PressResult result;
  const auto residual_norm = [&] {
    // A hanging node's force is its masters' (restricted: its own entry comes back zero).
    s.product.assign(s.force.begin(), s.force.end());
    BlockMatrix::restrict_to_masters(s.product, lattice_.hanging);
    double r = 0.0;
    for (std::size_t i = 0; i < n; ++i)
      if (!held_[i]) r = std::max(r, glm::length(s.product[i]));
    return r;
  };
  for (int it = 0; it < o.max_newton; ++it) {
    result.newton_iterations = it + 1;
    assemble(points, centre, radius, penalty, true, result);
    const double residual = residual_norm();
    const double scale = std::max(glm::length(result.probe_force_N), 1e-12);
    if (residual <= o.force_tolerance * scale) {
      // Equilibrium for these multipliers: take the contact forces as the new multipliers, and
      // stop once what they leave inside the probe is small.
      if (result.max_penetration_m <= o.penetration_tolerance_m) {
        result.converged = true;
        break;
      }
      for (std::size_t p = 0; p < points.size(); ++p) {
        const glm::dvec3 at = embedded_position(lattice_, x_, points[p]);
        multipliers_[p] =
            std::max(0.0, multipliers_[p] - penalty * (glm::length(at - centre) - radius));
      }
      continue;
    }
    std::fill(s.step.begin(), s.step.end(), glm::dvec3(0.0));
    const BlockMatrix::SolveStats cg =
        matrix.solve(s.force, s.step, held_, o.cg_tolerance, o.max_cg, lattice_.hanging);
    result.cg_iterations += cg.iterations;
    // Backtracking: the Newton matrix is the corotated linear one, softer than neo-Hookean
    // tissue in compression, so a full step may overshoot; halve it while the residual grows.
    s.start.assign(x_.begin(), x_.end());
    double fraction = 1.0;
    for (int tries = 0; tries < 4; ++tries) {
      for (std::size_t i = 0; i < n; ++i)
        if (!held_[i]) x_[i] = s.start[i] + fraction * s.step[i];
      if (tries == 3) break;
      PressResult probe_only;
      assemble(points, centre, radius, penalty, false, probe_only);
      const double next = residual_norm();
      if (std::isfinite(next) && next <= residual) break;
      fraction *= 0.5;
    }
  }
  return result;
}

void ElasticVolume::add_cell_matrix(std::size_t c, const glm::dmat3& r, double warp_tolerance,
                                    float scale) {
  Solver& s = *solver_;
  BlockMatrix& matrix = s.matrix(lattice_);
  if (s.warped.size() != lattice_.cells.size()) {
    s.warped.resize(lattice_.cells.size());
    s.warped_rotation.assign(lattice_.cells.size(), glm::dmat3(0.0));  // none valid yet
  }
  // R K R^T for the cell's rotation, kept while the cell turns less than the tolerance: the
  // rotation changes little from step to step and the products are most of an assembly.
  const glm::dmat3 change = r - s.warped_rotation[c];
  double drift = 0.0;
  for (int i = 0; i < 3; ++i)
    drift = std::max(drift, glm::length(change[i]));
  std::array<glm::mat3, 36>& blocks = s.warped[c];
  if (!(drift <= warp_tolerance) || warp_tolerance <= 0.0) {
    s.warped_rotation[c] = r;
    const HexStiffness& k = s.shapes[s.cell_shape[c]];
    const glm::dmat3 r_fill = lattice_.fill[c] * r;
    const glm::dmat3 rt = glm::transpose(r);
    std::size_t i = 0;
    for (std::size_t a = 0; a < 8; ++a)
      for (std::size_t b = a; b < 8; ++b)
        blocks[i++] = glm::mat3(r_fill * k[a][b] * rt);
  }
  const auto& slots = matrix.cell_slots(c);
  std::size_t i = 0;
  for (std::size_t a = 0; a < 8; ++a) {
    for (std::size_t b = a; b < 8; ++b, ++i) {
      const glm::mat3 block = scale * blocks[i];
      matrix.add(slots[a * 8 + b], block);
      if (b != a) matrix.add(slots[b * 8 + a], glm::transpose(block));
    }
  }
}

void ElasticVolume::assemble_elements(bool with_matrix, double warp_tolerance, double scale) {
  Solver& s = *solver_;
  if (with_matrix) s.matrix(lattice_).set_zero();  // built here on first use
  std::fill(s.force.begin(), s.force.end(), glm::dvec3(0.0));
  for (std::size_t c = 0; c < lattice_.cells.size(); ++c) {
    const auto& cell = lattice_.cells[c];
    const glm::dvec3 h = lattice_.cell_sides(c);
    const std::array<glm::dvec3, 8> g = centre_gradients(h);
    glm::dmat3 f(0.0);
    for (std::size_t a = 0; a < 8; ++a)
      f += glm::outerProduct(x_[cell[a]], g[a]);
    // Cells mostly outside the surface stay corotated: they are little tissue and may be
    // crushed flat, which neo-Hookean cannot take.
    const bool hyper = law_ == ElasticLaw::NeoHookean && lattice_.fill[c] >= 0.5;
    glm::dmat3 r(1.0);
    if (with_matrix || !hyper || tension_Pa_ != 0.0) r = polar_rotation(f);
    if (tension_Pa_ != 0.0) {
      // The resting tension pulls the corners towards the centre: -integral of sigma grad N_a,
      // sigma = t I turned with the cell (grad N_a's mean over the box is its centre value).
      const double pull = tension_Pa_ * h.x * h.y * h.z * lattice_.fill[c];
      for (std::size_t a = 0; a < 8; ++a)
        s.force[cell[a]] -= pull * (r * g[a]);
    }
    if (with_matrix || !hyper) {
      const HexStiffness& k = s.shapes[s.cell_shape[c]];
      const double fill = lattice_.fill[c];
      const glm::dmat3 rt = glm::transpose(r);
      const glm::dmat3 r_fill = fill * r;
      std::array<glm::dvec3, 8> u;
      for (std::size_t a = 0; a < 8; ++a)
        u[a] = rt * x_[cell[a]] - lattice_.rest[cell[a]];
      if (!hyper) {
        for (std::size_t a = 0; a < 8; ++a) {
          glm::dvec3 local(0.0);
          for (std::size_t b = 0; b < 8; ++b)
            local += k[a][b] * u[b];
          s.force[cell[a]] -= r_fill * local;
        }
      }
      if (with_matrix) add_cell_matrix(c, r, warp_tolerance, static_cast<float>(scale));
    }
    if (hyper) {
      // f_a = -integral of P grad N_a: the isochoric stress at the Gauss points, the volumetric
      // one at the centre.
      const double volume = h.x * h.y * h.z * lattice_.fill[c];
      const auto gq = gauss_gradients(h);
      for (std::size_t q = 0; q < 8; ++q) {
        glm::dmat3 fq(0.0);
        for (std::size_t a = 0; a < 8; ++a)
          fq += glm::outerProduct(x_[cell[a]], gq[q][a]);
        const glm::dmat3 p = neo_hookean_isochoric_stress(fq, mu_) * (0.125 * volume);
        for (std::size_t a = 0; a < 8; ++a)
          s.force[cell[a]] -= p * gq[q][a];
      }
      const glm::dmat3 p = neo_hookean_volumetric_stress(f, lambda_ + 2.0 * mu_ / 3.0) * volume;
      for (std::size_t a = 0; a < 8; ++a)
        s.force[cell[a]] -= p * g[a];
    }
  }
  if (!surroundings_.empty())
    for (std::size_t i = 0; i < surroundings_.size(); ++i)
      s.force[i] += surroundings_[i];
  if (!releasing_.empty())
    for (std::size_t i = 0; i < releasing_.size(); ++i)
      s.force[i] += releasing_[i];
}

void ElasticVolume::build_step_matrix() {
  (void)solver_->matrix(lattice_);
}

std::vector<glm::dvec3> ElasticVolume::node_forces() {
  assemble_elements(false, 0.0, 1.0);
  return solver_->force;
}

void ElasticVolume::fade_in_from(std::span<const glm::dvec3> before, double time_s) {
  if (before.size() != x_.size())
    throw std::invalid_argument("ElasticVolume::fade_in_from: one force per node");
  releasing_.clear();
  if (!(time_s > 0.0)) return;
  release_s_ = time_s;
  std::vector<glm::dvec3> now = node_forces();
  for (std::size_t i = 0; i < now.size(); ++i)
    now[i] = before[i] - now[i];
  releasing_ = std::move(now);
}

void ElasticVolume::set_releasing(std::vector<glm::dvec3> load, double time_s) {
  if (!load.empty() && load.size() != x_.size())
    throw std::invalid_argument("ElasticVolume::set_releasing: one load per node");
  releasing_ = time_s > 0.0 ? std::move(load) : std::vector<glm::dvec3>{};
  release_s_ = time_s;
}

void ElasticVolume::set_resting_tension(double tension_Pa) {
  if (!std::isfinite(tension_Pa) || tension_Pa < 0.0)
    throw std::invalid_argument("resting tension must be finite and >= 0 Pa");
  tension_Pa_ = tension_Pa;
  surroundings_.assign(tension_Pa > 0.0 ? x_.size() : 0, glm::dvec3(0.0));
  if (tension_Pa <= 0.0) return;
  // What the cells pull on the nodes at rest, taken by the surroundings: zero inside the
  // tissue, where neighbouring cells pull each node both ways.
  for (std::size_t c = 0; c < lattice_.cells.size(); ++c) {
    const glm::dvec3 h = lattice_.cell_sides(c);
    const std::array<glm::dvec3, 8> g = centre_gradients(h);
    const double pull = tension_Pa * h.x * h.y * h.z * lattice_.fill[c];
    for (std::size_t a = 0; a < 8; ++a)
      surroundings_[lattice_.cells[c][a]] += pull * g[a];
  }
}

void ElasticVolume::set_surroundings_load(std::vector<glm::dvec3> load) {
  if (!load.empty() && load.size() != x_.size())
    throw std::invalid_argument("ElasticVolume::set_surroundings_load: one load per node");
  surroundings_ = std::move(load);
}

void ElasticVolume::assemble(std::span<const EmbeddedPoint> points, const glm::dvec3& centre,
                             double radius, double penalty, bool with_matrix, PressResult& out) {
  Solver& s = *solver_;
  BlockMatrix& matrix = s.matrix(lattice_);
  assemble_elements(with_matrix, 0.0, 1.0);
  // Contact: each surface point inside the probe (or holding a multiplier) pushed out along the
  // probe's normal, F = max(0, multiplier - penalty * gap).
  glm::dvec3 probe(0.0);
  double penetration = 0.0;
  std::size_t contacts = 0;
  for (std::size_t p = 0; p < points.size(); ++p) {
    const EmbeddedPoint& ep = points[p];
    const glm::dvec3 at = embedded_position(lattice_, x_, ep);
    const glm::dvec3 d = at - centre;
    const double dist = glm::length(d);
    if (dist <= 0.0) continue;
    const double gap = dist - radius;
    const double push = multipliers_[p] - penalty * gap;
    if (push <= 0.0) continue;
    ++contacts;
    penetration = std::max(penetration, -gap);
    const glm::dvec3 normal = d / dist;
    const glm::dmat3 nn = glm::outerProduct(normal, normal) * penalty;
    const auto& cell = lattice_.cells[ep.cell];
    const auto& slots = matrix.cell_slots(ep.cell);
    for (std::size_t a = 0; a < 8; ++a) {
      s.force[cell[a]] += ep.weights[a] * push * normal;
      if (!with_matrix) continue;
      for (std::size_t b = 0; b < 8; ++b)
        matrix.add(slots[a * 8 + b], glm::mat3((ep.weights[a] * ep.weights[b]) * nn));
    }
    probe -= push * normal;
  }
  out.probe_force_N = probe;
  out.contacts = contacts;
  out.max_penetration_m = penetration;
}

}  // namespace bisturi::sim
