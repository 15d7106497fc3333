#include "bisturi/sim/volume/volume_body.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <optional>
#include <set>
#include <string>

#include <glm/geometric.hpp>
#include <glm/gtx/norm.hpp>

#include "bisturi/sim/errors.h"
#include "bisturi/sim/volume/lattice_cut.h"
#include "block_matrix.h"

namespace bisturi::sim {

namespace {

/// Where the lattice's motion takes `p` (positions or velocities of its nodes in `field`): in
/// its kept cell, or, outside every kept cell (a corner of a coarse cell in the air, where the
/// fine cells were not kept), extrapolated from the nearest kept cell within two positions.
/// False when there is none.
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

/// The compliance is one number, u^T A^-1 u: its error is about the square of the solve's
/// relative residual, so a loose solve gives it to well under a percent.
constexpr double kComplianceTolerance = 1e-2;

/// The volume under `body`: one level of cells of options.cell_m, or, with `refine` boxes and a
/// factor above 1, two, the cells meeting a box split into factor^3.
ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options,
                           const std::vector<TwoLevelOptions::Box>& refine, std::uint32_t factor) {
  if (!body.closed()) {
    throw SimInputError("a volume needs a closed surface: the solid has open boundaries");
  }
  if (!(options.cell_m > 0.0) || !std::isfinite(options.cell_m)) {
    throw SimInputError("volume cell size must be positive, got " + std::to_string(options.cell_m) +
                        " m");
  }
  // The surface at rest, its alive vertices numbered compactly.
  const Dlfl& mesh = body.mesh();
  std::vector<std::uint32_t> compact(mesh.vertex_capacity(), 0);
  std::vector<glm::dvec3> vertices;
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
    if (!mesh.alive(VertexId(i))) continue;
    compact[i] = static_cast<std::uint32_t>(vertices.size());
    vertices.push_back(body.rest_position(VertexId(i)));
  }
  const auto& indices = body.triangles().indices;
  std::vector<std::array<std::uint32_t, 3>> triangles(indices.size() / 3);
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (std::size_t c = 0; c < 3; ++c)
      triangles[t][c] = compact[indices[3 * t + c]];
  if (!refine.empty() && factor > 1) {
    TwoLevelOptions lattice;
    lattice.coarse_m = options.cell_m;
    lattice.factor = factor;
    lattice.refine = refine;
    ElasticVolume volume(build_two_level_lattice(vertices, triangles, lattice), options.material,
                         options.law);
    volume.set_resting_tension(options.resting_tension_Pa);
    return volume;
  }
  LatticeOptions lattice;
  lattice.finest_m = options.cell_m;
  lattice.coarsest_m = options.cell_m;
  ElasticVolume volume(build_hex_lattice(vertices, triangles, lattice), options.material,
                       options.law);
  volume.set_resting_tension(options.resting_tension_Pa);
  return volume;
}

/// The volume under `body` with options' refined cube (if any) split finer.
ElasticVolume build_volume(const SoftBody& body, const VolumeOptions& options) {
  if (!(options.refine_half_width_m > 0.0)) return build_volume(body, options, {}, 1);
  const glm::dvec3 half(options.refine_half_width_m);
  return build_volume(body, options,
                      {{options.refine_centre_m - half, options.refine_centre_m + half}},
                      options.refine_factor);
}

/// Boxes of side `fine_m` round points of `sheet` half that apart (one per half-cell they fall
/// in: the blade is sampled every step): what the cells along the sheet meet.
std::vector<TwoLevelOptions::Box> boxes_along(const BladeSheet& sheet, double fine_m) {
  std::vector<TwoLevelOptions::Box> boxes;
  std::set<std::array<std::int64_t, 3>> seen;
  const double step = 0.5 * fine_m;
  for (std::size_t k = 0; k + 1 < sheet.entry_m.size(); ++k) {
    const glm::dvec3 &a = sheet.entry_m[k], &b = sheet.entry_m[k + 1];
    const glm::dvec3 &c = sheet.tip_m[k + 1], &d = sheet.tip_m[k];
    const double along = std::max(glm::length(b - a), glm::length(c - d));
    const double down = std::max(glm::length(d - a), glm::length(c - b));
    const auto nu = static_cast<std::size_t>(std::ceil(along / step)) + 1;
    const auto nv = static_cast<std::size_t>(std::ceil(down / step)) + 1;
    for (std::size_t i = 0; i <= nu; ++i)
      for (std::size_t j = 0; j <= nv; ++j) {
        const double u = double(i) / double(nu), v = double(j) / double(nv);
        const glm::dvec3 p = (1 - v) * ((1 - u) * a + u * b) + v * ((1 - u) * d + u * c);
        const glm::dvec3 q = glm::floor(p / step);
        if (!seen.insert({std::int64_t(q.x), std::int64_t(q.y), std::int64_t(q.z)}).second)
          continue;
        boxes.push_back({p - glm::dvec3(step), p + glm::dvec3(step)});
      }
  }
  return boxes;
}

/// Per node of a separated lattice, its cells' tissue (volume times fill), and per node of the
/// lattice it was separated from (`origin` maps one to the other), the sum over its copies: a
/// node's load is shared among its copies by their tissue.
struct TissueShares {
  std::vector<double> of_node, of_origin;
  TissueShares(const HexLattice& lattice, std::span<const std::uint32_t> origin,
               std::size_t origins)
      : of_node(lattice.rest.size(), 0.0), of_origin(origins, 0.0) {
    for (std::size_t c = 0; c < lattice.cells.size(); ++c) {
      const glm::dvec3 h = lattice.cell_sides(c);
      for (const std::uint32_t n : lattice.cells[c])
        of_node[n] += h.x * h.y * h.z * lattice.fill[c];
    }
    for (std::size_t n = 0; n < of_node.size(); ++n)
      of_origin[origin[n]] += of_node[n];
  }
  /// Per node, its share of its origin's value.
  [[nodiscard]] std::vector<glm::dvec3> share(std::span<const std::uint32_t> origin,
                                              std::span<const glm::dvec3> of) const {
    std::vector<glm::dvec3> out(of_node.size());
    for (std::size_t n = 0; n < of_node.size(); ++n) {
      const std::uint32_t o = origin[n];
      out[n] = of_origin[o] > 0.0 ? of[o] * (of_node[n] / of_origin[o]) : glm::dvec3(0.0);
    }
    return out;
  }
};

}  // namespace

VolumeBody::VolumeBody(const SoftBody& body, const VolumeOptions& options)
    : volume_(build_volume(body, options)), options_(options) {
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
  // Holding a node puts it at rest: the motion it has is put back after.
  const std::vector<glm::dvec3> x(volume_.positions().begin(), volume_.positions().end());
  const std::vector<glm::dvec3> v(volume_.velocities().begin(), volume_.velocities().end());
  std::fill(embedded_.begin(), embedded_.end(), std::uint8_t{0});
  embed_slots(body);
  // The lips of earlier cuts on their own sides.
  for (std::uint32_t i = 0; i < lip_side_.size(); ++i) {
    if (lip_side_[i] == 0 || !embedded_[i]) continue;
    if (const auto e =
            embed_point_on_side(volume_.lattice(), body.rest_position(VertexId(i)), lip_side_[i]))
      embedding_[i] = *e;
  }
  hold_anchored(body);
  volume_.set_state(x, v);
  volume_.build_step_matrix();
  write_surface(body);
  ++lattice_version_;
}

void VolumeBody::split_again(const SoftBody& body) {
  // The lattice from the surface with every cut's cells split, separated along the earlier
  // cuts' sheets again in their order; `origin` takes its nodes to the unseparated one's.
  ElasticVolume unseparated = build_volume(body, options_, cut_boxes_, options_.cut_refine_factor);
  HexLattice lattice = unseparated.lattice();
  std::vector<std::uint32_t> origin(lattice.rest.size());
  for (std::uint32_t n = 0; n < origin.size(); ++n)
    origin[n] = n;
  for (const BladeSheet& sheet : cut_sheets_) {
    const LatticeSeparation separation =
        separate_along_sheet(lattice, sheet, unseparated.finest_cell_m());
    std::vector<std::uint32_t> composed(separation.origin.size());
    for (std::size_t n = 0; n < composed.size(); ++n)
      composed[n] = origin[separation.origin[n]];
    origin = std::move(composed);
  }
  // Each node moves as the current lattice moves it in a cell on the node's own side of the
  // wounds: read in the old cell that holds a point just inside one of the node's new cells
  // (the walls lie on cell faces, so that cell lies on the same side). Where the split cells
  // are the old ones, that is the node's old motion exactly.
  const HexLattice& old = volume_.lattice();
  std::vector<std::uint32_t> a_cell(lattice.rest.size(), UINT32_MAX);
  for (std::uint32_t c = 0; c < lattice.cells.size(); ++c)
    for (const std::uint32_t n : lattice.cells[c])
      if (a_cell[n] == UINT32_MAX) a_cell[n] = c;
  std::vector<glm::dvec3> x(lattice.rest.size()), v(lattice.rest.size());
  for (std::size_t n = 0; n < x.size(); ++n) {
    const glm::dvec3& rest = lattice.rest[n];
    std::optional<EmbeddedPoint> in_old;
    if (a_cell[n] != UINT32_MAX)
      in_old = embed_point(old, rest + 0.01 * (lattice.cell_centre(a_cell[n]) - rest));
    if (in_old) {
      const EmbeddedPoint at = embed_point_in(old, in_old->cell, rest);
      x[n] = embedded_position(old, volume_.positions(), at);
      v[n] = embedded_position(old, volume_.velocities(), at);
    } else if (!motion_at(old, volume_.positions(), rest, x[n]) ||
               !motion_at(old, volume_.velocities(), rest, v[n])) {
      x[n] = rest + volume_.held_offset();
      v[n] = volume_.held_velocity();
    }
  }
  BlockMatrix::expand(x, lattice.hanging);
  BlockMatrix::expand(v, lattice.hanging);
  // The surroundings' load of the unseparated lattice, each node's shared among its copies (the
  // separated lattice's own would hold the earlier wounds shut).
  std::vector<glm::dvec3> load;
  if (!unseparated.surroundings_load().empty())
    load = TissueShares(lattice, origin, unseparated.lattice().rest.size())
               .share(origin, unseparated.surroundings_load());
  const glm::dvec3 held_velocity = volume_.held_velocity();
  ElasticVolume next(std::move(lattice), options_.material, options_.law);
  next.set_resting_tension(unseparated.resting_tension_Pa());
  next.set_surroundings_load(std::move(load));
  next.set_state(x, v);
  next.set_held_velocity(held_velocity);
  volume_ = std::move(next);
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
  // Slots that died are skipped from now on; new ones (the cut's copies) embedded.
  const Dlfl& mesh = body.mesh();
  for (std::size_t i = 0; i < embedded_.size(); ++i)
    if (embedded_[i] && !mesh.alive(VertexId(static_cast<std::uint32_t>(i)))) embedded_[i] = 0;
  embed_slots(body);
}

std::vector<std::int8_t> lip_sides(const SoftBody& body, const CutResult& cut,
                                   const HexLattice& lattice) {
  const std::size_t slots = body.mesh().vertex_capacity();
  std::vector<std::int8_t> side(slots, 0);
  std::vector<double> lean(slots, 0.0);
  std::vector<std::uint8_t> lip(slots, 0);
  for (const VertexId v : cut.path)
    lip[v.idx] = 1;
  for (const VertexId v : cut.new_vertices)
    lip[v.idx] = 1;
  for (const VertexId v : cut.floor_vertices)  // on the sheet: no side, and none to give
    lip[v.idx] = 2;
  // Each lip leans to the side of the sheet its faces' other corners lie on.
  const auto& indices = body.triangles().indices;
  for (std::size_t t = 0; t + 2 < indices.size(); t += 3)
    for (std::size_t a = 0; a < 3; ++a) {
      if (!lip[indices[t + a]]) continue;
      for (std::size_t b = 0; b < 3; ++b)
        if (!lip[indices[t + b]])
          lean[indices[t + a]] += sheet_side(lattice, body.rest_position(VertexId(indices[t + b])));
    }
  for (std::size_t i = 0; i < slots; ++i)
    side[i] = lip[i] == 2 ? 0 : lean[i] > 0.0 ? 1 : lean[i] < 0.0 ? -1 : 0;
  return side;
}

std::size_t VolumeBody::cut(SoftBody& body, const CutResult& cut, const BladeSheet& sheet) {
  if (sheet.entry_m.size() < 2) {
    sync_topology(body);
    return 0;
  }
  const Dlfl& mesh = body.mesh();
  const auto x = body.positions();
  // The sheet in the rest frame: each point moved back by the nearest vertex's displacement.
  const auto to_rest = [&](const glm::dvec3& p) {
    double best = INFINITY;
    glm::dvec3 shift(0.0);
    for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
      if (!mesh.alive(VertexId(i))) continue;
      const double d = glm::length2(x[i] - p);
      if (d >= best) continue;
      best = d;
      shift = x[i] - body.rest_position(VertexId(i));
    }
    return p - shift;
  };
  // A sample (one is taken each tissue step) whose entry and tip are both nearer than a
  // twentieth of a cell to the last one kept adds nothing to the sheet (separate_along_sheet
  // skips it too): only the others are taken back to rest.
  const double min_step = 0.05 * options_.cell_m / std::max(1u, options_.cut_refine_factor);
  BladeSheet rest_sheet;
  std::size_t last = 0;
  for (std::size_t k = 0; k < sheet.entry_m.size(); ++k) {
    const bool final = k + 1 == sheet.entry_m.size();
    if (k > 0 && !final && glm::length(sheet.entry_m[k] - sheet.entry_m[last]) < min_step &&
        glm::length(sheet.tip_m[k] - sheet.tip_m[last]) < min_step)
      continue;
    last = k;
    rest_sheet.entry_m.push_back(to_rest(sheet.entry_m[k]));
    rest_sheet.tip_m.push_back(to_rest(sheet.tip_m[k]));
  }
  bool refined = false;
  if (options_.cut_refine_factor > 1 && !(options_.refine_half_width_m > 0.0) && body.closed()) {
    // The cells the sheet passes through, or passes within half a fine cell of, split before
    // they part, with those of the earlier cuts. The vertices are embedded in the refined
    // lattice only if nothing parts (they are embedded in the separated one below otherwise).
    const std::vector<TwoLevelOptions::Box> boxes =
        boxes_along(rest_sheet, options_.cell_m / options_.cut_refine_factor);
    cut_boxes_.insert(cut_boxes_.end(), boxes.begin(), boxes.end());
    if (cut_sheets_.empty())
      take_motion(build_volume(body, options_, cut_boxes_, options_.cut_refine_factor));
    else
      split_again(body);
    refined = true;
  }
  const HexLattice& old = volume_.lattice();
  HexLattice lattice = old;
  const LatticeSeparation separation =
      separate_along_sheet(lattice, rest_sheet, volume_.finest_cell_m());
  if (separation.new_nodes == 0) {
    if (refined)
      embed_again(body);
    else
      sync_topology(body);
    return 0;
  }
  cut_sheets_.push_back(rest_sheet);
  // The nodes' motion and loads: a copy moves as its node did and takes the share of its load
  // from the surroundings that its cells' tissue holds.
  const std::size_t nodes = lattice.rest.size();
  std::vector<glm::dvec3> nx(nodes), nv(nodes), load;
  for (std::size_t n = 0; n < nodes; ++n) {
    const std::uint32_t o = separation.origin[n];
    nx[n] = volume_.positions()[o];
    nv[n] = volume_.velocities()[o];
  }
  const TissueShares tissue(lattice, separation.origin, old.rest.size());
  const auto share = [&](std::span<const glm::dvec3> of_origin) {
    return tissue.share(separation.origin, of_origin);
  };
  if (!volume_.surroundings_load().empty()) load = share(volume_.surroundings_load());
  const glm::dvec3 held_velocity = volume_.held_velocity();
  const double tension = volume_.resting_tension_Pa();
  ElasticVolume next(std::move(lattice), options_.material, options_.law);
  next.set_resting_tension(tension);
  next.set_surroundings_load(std::move(load));
  // What each node felt before the cut, shared among its copies: the cut changes nothing at
  // once and lets go over the release time.
  next.set_state(nx, nv);
  next.fade_in_from(share(volume_.node_forces()), options_.tension_release_s);
  volume_ = std::move(next);
  separated_faces_ += separation.separated_faces;

  // Every vertex embedded again on its side: the lips by the surface's side of the incision,
  // the rest by where they are.
  // The earlier cuts' lips keep the sides they were given.
  const std::vector<std::int8_t> sides = lip_sides(body, cut, volume_.lattice());
  lip_side_.resize(mesh.vertex_capacity(), 0);
  for (const auto* lips : {&cut.path, &cut.new_vertices, &cut.floor_vertices})
    for (const VertexId v : *lips)
      lip_side_[v.idx] = sides[v.idx];
  embedding_.resize(mesh.vertex_capacity());
  embedded_.assign(mesh.vertex_capacity(), 0);
  loaded_.resize(mesh.vertex_capacity(), 0);
  for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
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
  ++lattice_version_;
  hold_anchored(body);
  volume_.set_state(nx, nv);
  volume_.set_held_velocity(held_velocity);
  volume_.build_step_matrix();
  write_surface(body);
  return separation.separated_faces;
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

StepStats VolumeBody::step(SoftBody& body, const IntegratorOptions& options,
                           std::vector<SimEvent>& events, std::uint32_t body_index,
                           std::uint64_t step_index) {
  StepStats stats;
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
