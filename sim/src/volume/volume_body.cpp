#include "bisturi/sim/volume/volume_body.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <optional>
#include <string>

#include <glm/geometric.hpp>
#include <glm/gtx/norm.hpp>

#include "bisturi/sim/errors.h"
#include "bisturi/sim/volume/lattice_cut.h"
#include "block_matrix.h"
#include "volume_build.h"

namespace bisturi::sim {

namespace {

/// The compliance is one number, u^T A^-1 u: its error is about the square of the solve's
/// relative residual, so a loose solve gives it to well under a percent.
constexpr double kComplianceTolerance = 1e-2;

}  // namespace

bool motion_at(const HexLattice& lattice, std::span<const glm::dvec3> field, const glm::dvec3& p,
               glm::dvec3& out) {
  if (const std::optional<EmbeddedPoint> at = embed_point(lattice, p)) {
    out = embedded_position(lattice, field, *at);
    return true;
  }
  const auto ijk = lattice.locate(p);
  const auto d = lattice.cell_dims();
  std::int32_t best = -1;
  double best_distance = INFINITY;
  for (int dk = -2; dk <= 2; ++dk)
    for (int dj = -2; dj <= 2; ++dj)
      for (int di = -2; di <= 2; ++di) {
        const long i = long(ijk[0]) + di, j = long(ijk[1]) + dj, k = long(ijk[2]) + dk;
        if (i < 0 || j < 0 || k < 0 || i >= long(d[0]) || j >= long(d[1]) || k >= long(d[2]))
          continue;
        const std::int32_t c =
            lattice.cell_at[(std::size_t(k) * d[1] + std::size_t(j)) * d[0] + std::size_t(i)];
        if (c < 0) continue;
        const double distance = glm::length(lattice.cell_centre(std::size_t(c)) - p);
        if (distance < best_distance) {
          best_distance = distance;
          best = c;
        }
      }
  if (best < 0) return false;
  // Trilinear weights past the cell's faces: the cell's motion, continued.
  out = embedded_position(lattice, field,
                          embed_point_in(lattice, static_cast<std::uint32_t>(best), p));
  return true;
}

namespace {

/// The surface at rest, its alive vertices numbered compactly.
struct RestSurface {
  std::vector<glm::dvec3> vertices;
  std::vector<std::array<std::uint32_t, 3>> triangles;
};

RestSurface rest_surface(const SoftBody& body) {
  const Dlfl& mesh = body.mesh();
  RestSurface out;
  std::vector<std::uint32_t> compact(mesh.vertex_capacity(), 0);
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    if (!mesh.alive(VertexId(i))) continue;
    compact[i] = static_cast<std::uint32_t>(out.vertices.size());
    out.vertices.push_back(body.rest_position(VertexId(i)));
  }
  const auto& indices = body.triangles().indices;
  out.triangles.resize(indices.size() / 3);
  for (std::size_t t = 0; t < out.triangles.size(); ++t)
    for (std::size_t c = 0; c < 3; ++c)
      out.triangles[t][c] = compact[indices[3 * t + c]];
  return out;
}

TwoLevelOptions two_level(const VolumeOptions& options,
                          const std::vector<TwoLevelOptions::Box>& refine, std::uint32_t factor) {
  TwoLevelOptions lattice;
  lattice.coarse_m = options.cell_m;
  lattice.factor = factor;
  lattice.refine = refine;
  return lattice;
}

}  // namespace

ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options,
                           const std::vector<TwoLevelOptions::Box>& refine, std::uint32_t factor,
                           const FineShares* shares) {
  if (!body.closed()) {
    throw SimInputError("a volume needs a closed surface: the solid has open boundaries");
  }
  if (!(options.cell_m > 0.0) || !std::isfinite(options.cell_m)) {
    throw SimInputError("volume cell size must be positive, got " + std::to_string(options.cell_m) +
                        " m");
  }
  const RestSurface surface = rest_surface(body);
  if (!refine.empty() && factor > 1) {
    ElasticVolume volume(build_two_level_lattice(surface.vertices, surface.triangles,
                                                 two_level(options, refine, factor), {}, shares),
                         options.material, options.law);
    volume.set_resting_tension(options.resting_tension_Pa);
    return volume;
  }
  LatticeOptions lattice;
  lattice.finest_m = options.cell_m;
  lattice.coarsest_m = options.cell_m;
  ElasticVolume volume(build_hex_lattice(surface.vertices, surface.triangles, lattice),
                       options.material, options.law);
  volume.set_resting_tension(options.resting_tension_Pa);
  return volume;
}

FineShares cut_fine_shares(const SoftBody& body, const VolumeOptions& options) {
  if (options.cut_refine_factor <= 1 || options.refine_half_width_m > 0.0 || !body.closed())
    return {};
  const RestSurface surface = rest_surface(body);
  return two_level_fine_shares(surface.vertices, surface.triangles,
                               two_level(options, {}, options.cut_refine_factor));
}

ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options) {
  if (!(options.refine_half_width_m > 0.0)) return build_volume(body, options, {}, 1);
  const glm::dvec3 half(options.refine_half_width_m);
  return build_volume(body, options,
                      {{options.refine_centre_m - half, options.refine_centre_m + half}},
                      options.refine_factor);
}

VolumeBody::VolumeBody(const SoftBody& body, const VolumeOptions& options)
    : volume_(build_volume(body, options)),
      options_(options),
      cut_shares_(cut_fine_shares(body, options)) {
  target_stiffness_N_per_m_ = options.target_stiffness_N_per_m > 0.0
                                  ? options.target_stiffness_N_per_m
                                  : 20.0 * volume_.youngs_modulus_Pa() * volume_.finest_cell_m();
  embed_slots(body);
  hold_anchored(body);
  volume_.build_step_matrix();
}

void VolumeBody::hold_anchored(const SoftBody& body) {
  for (std::uint32_t i = 0; i < embedded_.size(); ++i) {
    if (!embedded_[i] || !body.anchored(VertexId(i))) continue;
    for (const std::uint32_t node : volume_.lattice().cells[embedding_[i].cell])
      volume_.hold(node);
  }
}

bool VolumeBody::should_follow(const glm::dvec3& point_m) const {
  if (!options_.refine_follows || options_.refine_factor <= 1) return false;
  // A lattice built again from the surface would have no wounds: once one is cut, the box stays.
  if (separated_faces_ > 0) return false;
  const glm::dvec3 d = glm::abs(point_m - options_.refine_centre_m);
  return std::max({d.x, d.y, d.z}) > 0.5 * options_.refine_half_width_m;
}

void VolumeBody::refocus(SoftBody& body, const glm::dvec3& centre_m) {
  const auto begin = std::chrono::steady_clock::now();
  VolumeOptions options = options_;
  options.refine_centre_m = centre_m;
  rebuild(body, build_volume(body, options));
  options_ = options;
  ++refocus_count_;
  longest_refocus_ms_ = std::max(
      longest_refocus_ms_,
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count());
}

void VolumeBody::rebuild(SoftBody& body, ElasticVolume next) {
  take_motion(std::move(next));
  embed_again(body);
}

void VolumeBody::take_motion(ElasticVolume next) {
  // The new nodes where the old lattice has moved their rest positions to; a node far from
  // every old cell (none should be: both fill the same surface) moves with the supports.
  const HexLattice& old = volume_.lattice();
  const std::vector<glm::dvec3>& rest = next.lattice().rest;
  std::vector<glm::dvec3> x(rest.size()), v(rest.size());
  for (std::size_t i = 0; i < rest.size(); ++i) {
    if (!motion_at(old, volume_.positions(), rest[i], x[i]) ||
        !motion_at(old, volume_.velocities(), rest[i], v[i])) {
      x[i] = rest[i] + volume_.held_offset();
      v[i] = volume_.held_velocity();
    }
  }
  // A hanging node on its new faces, whatever the old cells gave it.
  BlockMatrix::expand(x, next.lattice().hanging);
  BlockMatrix::expand(v, next.lattice().hanging);
  const glm::dvec3 held_velocity = volume_.held_velocity();
  volume_ = std::move(next);
  volume_.set_state(x, v);
  volume_.set_held_velocity(held_velocity);
}

void VolumeBody::embed_again(SoftBody& body) {
  wake();
  // Holding a node puts it at rest: the motion it has is put back after.
  const std::vector<glm::dvec3> x(volume_.positions().begin(), volume_.positions().end());
  const std::vector<glm::dvec3> v(volume_.velocities().begin(), volume_.velocities().end());
  // Every vertex on its side of the wounds: a lip on the side its cut gave it, the others by
  // where they lie (in a lattice with no wound, simply the cell they lie in).
  const Dlfl& mesh = body.mesh();
  const std::size_t slots = mesh.vertex_capacity();
  lip_side_.resize(slots, 0);
  embedding_.resize(slots);
  embedded_.assign(slots, 0);
  loaded_.resize(slots, 0);
  for (std::uint32_t i = 0; i < slots; ++i) {
    if (!mesh.alive(VertexId(i))) {
      lip_side_[i] = 0;
      continue;
    }
    const auto e =
        embed_point_on_side(volume_.lattice(), body.rest_position(VertexId(i)), lip_side_[i]);
    if (!e) continue;
    embedding_[i] = *e;
    embedded_[i] = 1;
  }
  hold_anchored(body);
  volume_.set_state(x, v);
  volume_.build_step_matrix();
  write_surface(body);
  ++lattice_version_;
}

void VolumeBody::embed_slots(const SoftBody& body) {
  const Dlfl& mesh = body.mesh();
  const std::size_t capacity = mesh.vertex_capacity();
  embedding_.resize(capacity);
  embedded_.resize(capacity, 0);
  loaded_.resize(capacity, 0);
  // The vertices not yet embedded, at rest, embedded in one call.
  std::vector<std::uint32_t> slots;
  std::vector<glm::dvec3> rest;
  for (std::size_t i = 0; i < capacity; ++i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    if (!mesh.alive(v) || embedded_[i]) continue;
    slots.push_back(v.idx);
    rest.push_back(body.rest_position(v));
  }
  const std::vector<EmbeddedPoint> points = embed_points(volume_.lattice(), rest);
  for (std::size_t k = 0; k < slots.size(); ++k) {
    embedding_[slots[k]] = points[k];
    embedded_[slots[k]] = 1;
  }
}

void VolumeBody::sync_topology(const SoftBody& body) {
  wake();
  // Slots that died are skipped from now on; new ones (the cut's copies) embedded.
  const Dlfl& mesh = body.mesh();
  for (std::size_t i = 0; i < embedded_.size(); ++i)
    if (embedded_[i] && !mesh.alive(VertexId(static_cast<std::uint32_t>(i)))) embedded_[i] = 0;
  embed_slots(body);
}

std::size_t VolumeBody::embedded_vertices() const {
  return static_cast<std::size_t>(std::count(embedded_.begin(), embedded_.end(), 1));
}

void VolumeBody::gather_loads(const SoftBody& body) {
  loads_.clear();
  const auto& forces = body.external_forces();
  for (const std::uint32_t i : body.loaded_vertices()) {
    if (loaded_[i] || !embedded_[i]) continue;  // a vertex listed twice carries one sum
    loaded_[i] = 1;
    loads_.push_back({embedding_[i], forces[i], glm::dmat3(0.0)});
  }
  for (const std::uint32_t i : body.loaded_vertices())
    loaded_[i] = 0;
  for (std::vector<PointLoad>& probe : probe_loads_)
    probe.clear();
  for (const SoftBody::ContactTerm& c : body.contacts()) {
    if (!embedded_[c.vertex]) continue;
    const PointLoad load{embedding_[c.vertex], glm::dvec3(0.0),
                         c.stiffness_N_per_m * glm::outerProduct(c.normal, c.normal)};
    loads_.push_back(load);
    if (c.probe < 0) continue;
    const auto probe = static_cast<std::size_t>(c.probe);
    if (probe >= probe_loads_.size()) {
      probe_loads_.resize(probe + 1);
      probe_normal_.resize(probe + 1);
      probe_compliance_.resize(probe + 1, 0.0);
      probe_speed_.resize(probe + 1, 0.0);
    }
    probe_loads_[probe].push_back(load);
    probe_normal_[probe] = c.normal;
  }
  if (body.kinematic_count() == 0) return;
  const auto nodes = volume_.positions();
  for (std::uint32_t i = 0; i < embedded_.size(); ++i) {
    if (!embedded_[i] || !body.kinematic(VertexId(i))) continue;
    const glm::dvec3 at = embedded_position(volume_.lattice(), nodes, embedding_[i]);
    const double k = target_stiffness_N_per_m_;
    loads_.push_back({embedding_[i], k * (body.kinematic_target(VertexId(i)) - at), glm::dmat3(k)});
  }
}

double VolumeBody::probe_step_compliance(std::size_t p, double dt_s) {
  if (probe_loads_[p].empty()) return 0.0;
  // The step's own response to the tip moving on by d: the probe's reaction grows by k d (k its
  // coupling), spread over the patch by the coupling's shares, and the patch gives g = -c k d
  // with c the patch's compliance in the step's matrix, which holds the coupling's stiffness on
  // each patch vertex; the force after the step grows by k (d + g) = k (1 - k c) d. As a
  // compliance in series with the coupling: c / (1 - k c).
  const glm::dvec3& n = probe_normal_[p];
  double coupling = 0.0;
  for (const PointLoad& load : probe_loads_[p])
    coupling += glm::dot(n, load.stiffness_N_per_m * n);
  const double held =
      volume_.step_compliance(probe_loads_[p], n, dt_s, kComplianceTolerance, options_.max_cg);
  const double kept = 1.0 - coupling * held;
  return kept > 0.0 ? held / kept : 0.0;
}

double VolumeBody::probe_step_speed(std::size_t p) const {
  const glm::dvec3& n = probe_normal_[p];
  double total = 0.0, speed = 0.0;
  for (const PointLoad& load : probe_loads_[p]) {
    const double k = glm::dot(n, load.stiffness_N_per_m * n);
    total += k;
    speed +=
        k * glm::dot(n, embedded_position(volume_.lattice(), volume_.velocities(), load.point));
  }
  return total > 0.0 ? speed / total : 0.0;
}

void VolumeBody::write_surface(SoftBody& body) const {
  auto& x = body.positions();
  auto& v = body.velocities();
  const auto nodes = volume_.positions();
  const auto speeds = volume_.velocities();
  for (std::size_t i = 0; i < embedded_.size(); ++i) {
    if (!embedded_[i]) continue;
    x[i] = embedded_position(volume_.lattice(), nodes, embedding_[i]);
    v[i] = embedded_position(volume_.lattice(), speeds, embedding_[i]);
  }
}

void VolumeBody::count_quiet_step(SoftBody& body, const IntegratorOptions& options) {
  const auto still = [](const glm::dvec3& v) { return v == glm::dvec3(0.0); };
  bool quiet = options.sleeping && loads_.empty() && still(volume_.held_velocity());
  const double slow2 = options_.sleep_speed_m_s * options_.sleep_speed_m_s;
  for (const glm::dvec3& v : volume_.velocities())
    quiet = quiet && glm::length2(v) < slow2;
  // A wound's walls still letting go move the tissue on, however slowly (ElasticVolume's fading
  // load); a tenth of a millinewton left on a node no longer does.
  constexpr double kLetGo_N = 1e-4;
  for (const glm::dvec3& load : volume_.releasing())
    quiet = quiet && glm::length2(load) < kLetGo_N * kLetGo_N;
  quiet_steps_ = quiet ? quiet_steps_ + 1 : 0;
  if (quiet_steps_ < options.sleep_steps) return;
  // Asleep: at rest where it is, the surface too (the step's saved state is scratch now).
  saved_x_.assign(volume_.positions().begin(), volume_.positions().end());
  saved_v_.assign(saved_x_.size(), glm::dvec3(0.0));
  volume_.set_state(saved_x_, saved_v_);
  write_surface(body);
  asleep_ = true;
}

StepStats VolumeBody::step(SoftBody& body, const IntegratorOptions& options,
                           std::vector<SimEvent>& events, std::uint32_t body_index,
                           std::uint64_t step_index) {
  StepStats stats;
  ++steps_;
  stats.free_vertices = static_cast<std::uint32_t>(embedded_vertices());
  stats.awake_vertices = stats.free_vertices;
  std::fill(probe_compliance_.begin(), probe_compliance_.end(), 0.0);
  std::fill(probe_speed_.begin(), probe_speed_.end(), 0.0);
  if (body.frozen()) {
    body.clear_forces();
    return stats;
  }
  if (body.mesh().vertex_capacity() != embedded_.size()) sync_topology(body);
  gather_loads(body);
  if (asleep_) {
    if (loads_.empty()) {
      ++asleep_steps_;
      stats.awake_vertices = 0;
      body.clear_forces();
      return stats;
    }
    wake();
  }
  saved_x_.assign(volume_.positions().begin(), volume_.positions().end());
  saved_v_.assign(volume_.velocities().begin(), volume_.velocities().end());
  const double max_speed2 = options.max_speed_m_s * options.max_speed_m_s;
  for (int attempt = 0; attempt <= options.max_retry_halvings; ++attempt) {
    const int substeps = 1 << attempt;
    DynamicOptions dynamic;
    dynamic.dt_s = options.dt_s / substeps;
    dynamic.gravity_m_s2 = options_.weight_supported ? glm::dvec3(0.0) : options.gravity_m_s2;
    dynamic.cg_tolerance = options_.cg_tolerance;
    dynamic.max_cg = options_.max_cg;
    StepStats trial = stats;
    trial.substeps = substeps;
    for (int s = 0; s < substeps; ++s) {
      const DynamicResult r = volume_.advance(loads_, dynamic);
      trial.cg_iterations += r.cg_iterations;
      trial.relative_residual = r.relative_residual;
    }
    std::string reason;
    for (const glm::dvec3& v : volume_.velocities()) {
      const double s2 = glm::length2(v);
      if (!std::isfinite(s2)) {
        reason = "non-finite state";
        break;
      }
      if (s2 > max_speed2) {
        reason = "speed " + std::to_string(std::sqrt(s2)) + " m/s above the limit";
        break;
      }
    }
    if (reason.empty()) {
      trial.rolled_back = attempt > 0;
      // The probes' compliance under their patches, from this step's matrix (a step cut into
      // substeps has a shorter one: none then).
      if (substeps == 1) {
        for (std::size_t p = 0; p < probe_loads_.size(); ++p) {
          probe_compliance_[p] = probe_step_compliance(p, dynamic.dt_s);
          probe_speed_[p] = probe_step_speed(p);
        }
      }
      write_surface(body);
      count_quiet_step(body, options);
      body.clear_forces();
      return trial;
    }
    events.push_back({SimEventKind::RolledBack, body_index, step_index, substeps, reason});
    volume_.set_state(saved_x_, saved_v_);
  }
  events.push_back({SimEventKind::Frozen, body_index, step_index, 1 << options.max_retry_halvings,
                    "still diverging with the smallest substep: the solid is frozen"});
  saved_v_.assign(saved_v_.size(), glm::dvec3(0.0));
  volume_.set_state(saved_x_, saved_v_);
  write_surface(body);
  body.freeze();
  stats.frozen = true;
  stats.rolled_back = true;
  return stats;
}

}  // namespace bisturi::sim
