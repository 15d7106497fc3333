// A VolumeBody cut (volume_body.h): the cells along the blade split, the lattice separated along
// its sheet, every vertex embedded again on its side.

#include "bisturi/sim/volume/volume_body.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <utility>
#include <vector>

#include <glm/geometric.hpp>
#include <glm/gtx/norm.hpp>

#include "bisturi/sim/volume/lattice_cut.h"
#include "block_matrix.h"
#include "volume_build.h"

namespace bisturi::sim {

namespace {

/// The alive vertices in order of their x: the nearest to a point is found by walking out from
/// the point's x both ways until a vertex is further in x alone than the nearest so far.
class NearestVertex {
 public:
  NearestVertex(const Dlfl& mesh, std::span<const glm::dvec3> x) : x_(x) {
    for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i)
      if (mesh.alive(VertexId(i))) by_x_.emplace_back(x[i].x, i);
    std::sort(by_x_.begin(), by_x_.end());
  }
  /// The nearest vertex to p, the lowest index of those equally near (as a scan in index order
  /// finds it); UINT32_MAX when none is alive.
  [[nodiscard]] std::uint32_t nearest(const glm::dvec3& p) const {
    double best = INFINITY;
    std::uint32_t found = UINT32_MAX;
    const auto consider = [&](std::uint32_t i) {
      const double d = glm::length2(x_[i] - p);
      if (d < best || (d == best && i < found)) {
        best = d;
        found = i;
      }
    };
    // A vertex dx away in x is at least dx * dx away squared (the sum rounds no lower).
    const auto start = static_cast<std::size_t>(
        std::lower_bound(by_x_.begin(), by_x_.end(), std::pair(p.x, std::uint32_t{0})) -
        by_x_.begin());
    for (std::size_t k = start; k < by_x_.size(); ++k) {
      const double dx = by_x_[k].first - p.x;
      if (dx * dx > best) break;
      consider(by_x_[k].second);
    }
    for (std::size_t k = start; k-- > 0;) {
      const double dx = p.x - by_x_[k].first;
      if (dx * dx > best) break;
      consider(by_x_[k].second);
    }
    return found;
  }

 private:
  std::span<const glm::dvec3> x_;
  std::vector<std::pair<double, std::uint32_t>> by_x_;  ///< each alive vertex's x and index
};

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

void VolumeBody::split_again(const SoftBody& body) {
  // The lattice from the surface with every cut's cells split, separated along the earlier
  // cuts' sheets again in their order; `origin` takes its nodes to the unseparated one's.
  ElasticVolume unseparated =
      build_volume(body, options_, cut_boxes_, options_.cut_refine_factor, &cut_shares_);
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
  // are the old ones, that is the node's old motion exactly. A node where an old one was takes
  // what that one had still to let go of (the fading load lies on the earlier wounds' walls,
  // whose cells are the old ones).
  const HexLattice& old = volume_.lattice();
  const std::span<const glm::dvec3> old_release = volume_.releasing();
  std::vector<glm::dvec3> release(old_release.empty() ? 0 : lattice.rest.size(), glm::dvec3(0.0));
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
      for (std::size_t q = 0; q < 8 && !release.empty(); ++q)
        if (at.weights[q] > 1.0 - 1e-9) release[n] = old_release[old.cells[at.cell][q]];
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
  next.set_releasing(std::move(release), volume_.release_time_s());
  volume_ = std::move(next);
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
  wake();
  if (sheet.entry_m.size() < 2) {
    sync_topology(body);
    return 0;
  }
  const Dlfl& mesh = body.mesh();
  const auto& x = body.positions();
  // The sheet in the rest frame: each point moved back by the nearest vertex's displacement.
  const NearestVertex nearest(mesh, x);
  const auto to_rest = [&](const glm::dvec3& p) {
    const std::uint32_t i = nearest.nearest(p);
    if (i == UINT32_MAX) return p;
    return p - (x[i] - body.rest_position(VertexId(i)));
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
      take_motion(
          build_volume(body, options_, cut_boxes_, options_.cut_refine_factor, &cut_shares_));
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
  volume_.set_held_velocity(held_velocity);
  separated_faces_ += separation.separated_faces;

  // This cut's lips by the surface's side of the incision; the earlier cuts' keep theirs.
  const std::vector<std::int8_t> sides = lip_sides(body, cut, volume_.lattice());
  lip_side_.resize(mesh.vertex_capacity(), 0);
  for (const auto* lips : {&cut.path, &cut.new_vertices, &cut.floor_vertices})
    for (const VertexId v : *lips)
      lip_side_[v.idx] = sides[v.idx];
  embed_again(body);
  return separation.separated_faces;
}

}  // namespace bisturi::sim
