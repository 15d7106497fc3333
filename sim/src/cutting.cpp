#include "bisturi/sim/cutting.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <map>
#include <queue>
#include <set>

#include <glm/common.hpp>
#include <glm/geometric.hpp>
#include <glm/gtc/type_precision.hpp>

#include "bisturi/sim/errors.h"
#include "bisturi/sim/units.h"
#include "vertex_corners.h"
#include "wound_walls.h"

namespace bisturi::sim {
namespace {

std::vector<CornerId> vertex_corners(const Dlfl& mesh, VertexId v) {
  std::vector<CornerId> out;
  for_each_corner(mesh, v, [&](CornerId c) { out.push_back(c); });
  return out;
}

bool on_boundary(const Dlfl& mesh, VertexId v) {
  return any_corner(mesh, v, [&](CornerId c) { return mesh.is_bounding(mesh.face(c)); });
}

bool has_real_face(const Dlfl& mesh, VertexId v) {
  return any_corner(mesh, v, [&](CornerId c) {
    return !mesh.is_bounding(mesh.face(c)) && !mesh.is_point_sphere(c);
  });
}

double point_segment_distance(const glm::dvec3& p, const glm::dvec3& a, const glm::dvec3& b) {
  double t = 0.0;
  return glm::length(p - closest_point_on_segment(p, a, b, t));
}

/// The vertices a cut may start, end or turn at (alive, with a real face), in a uniform grid:
/// the nearest to a blade point is found among the cells about it, not by a scan of every
/// vertex (a scan per blade point cost a 20,000-vertex surface tens of milliseconds). The same
/// vertex as a scan: the nearest, the lowest index among equals.
class VertexGrid {
 public:
  explicit VertexGrid(const SoftBody& body) : x_(body.positions()) {
    const Dlfl& mesh = body.mesh();
    std::vector<std::uint32_t> kept;
    for (std::uint32_t i = 0; i < mesh.vertex_capacity(); ++i) {
      if (!mesh.alive(VertexId(i)) || !has_real_face(mesh, VertexId(i))) continue;
      kept.push_back(i);
      lo_ = glm::min(lo_, x_[i]);
      hi_ = glm::max(hi_, x_[i]);
    }
    if (kept.empty()) return;
    // About two vertices a cell.
    const glm::dvec3 size = glm::max(hi_ - lo_, glm::dvec3(1e-9));
    cell_ = std::max(std::cbrt(size.x * size.y * size.z * 2.0 / static_cast<double>(kept.size())),
                     1e-6);
    for (int a = 0; a < 3; ++a)
      dims_[a] = std::min<std::int64_t>(static_cast<std::int64_t>(size[a] / cell_) + 1, 1024);
    start_.assign(static_cast<std::size_t>(dims_[0] * dims_[1] * dims_[2]) + 1, 0);
    for (const std::uint32_t i : kept)
      ++start_[index(cell_of(x_[i])) + 1];
    for (std::size_t c = 1; c < start_.size(); ++c)
      start_[c] += start_[c - 1];
    members_.resize(kept.size());
    std::vector<std::uint32_t> fill(start_.begin(), start_.end() - 1);
    for (const std::uint32_t i : kept)  // ascending: each cell's members too
      members_[fill[index(cell_of(x_[i]))]++] = i;
  }

  [[nodiscard]] VertexId nearest(const glm::dvec3& p) const {
    if (members_.empty()) return VertexId{};
    const glm::i64vec3 c = cell_of(p);  // the cell of p clamped into the grid
    std::uint32_t best = 0;
    double best_d2 = std::numeric_limits<double>::infinity();
    const std::int64_t most = std::max({dims_[0], dims_[1], dims_[2]});
    for (std::int64_t r = 0; r <= most; ++r) {
      for (std::int64_t k = c.z - r; k <= c.z + r; ++k) {
        for (std::int64_t j = c.y - r; j <= c.y + r; ++j) {
          // Ring r only (the cells at Chebyshev distance r): a whole row on its top, bottom and
          // side faces, else the row's two ends.
          const bool face = std::abs(k - c.z) == r || std::abs(j - c.y) == r;
          const std::int64_t step = face || r == 0 ? 1 : 2 * r;
          for (std::int64_t i = c.x - r; i <= c.x + r; i += step) {
            if (i < 0 || j < 0 || k < 0 || i >= dims_[0] || j >= dims_[1] || k >= dims_[2])
              continue;
            const std::size_t cell = index({i, j, k});
            for (std::uint32_t m = start_[cell]; m < start_[cell + 1]; ++m) {
              const std::uint32_t v = members_[m];
              const glm::dvec3 d = x_[v] - p;
              const double d2 = glm::dot(d, d);
              if (d2 < best_d2 || (d2 == best_d2 && v < best)) {
                best_d2 = d2;
                best = v;
              }
            }
          }
        }
      }
      // Any vertex beyond ring r is at least r cells from p's place in the grid (and from p:
      // clamping a point into a box brings it no further from the box's points).
      const double reach = static_cast<double>(r) * cell_;
      if (best_d2 < std::numeric_limits<double>::infinity() && best_d2 < reach * reach) break;
    }
    return VertexId(best);
  }

 private:
  [[nodiscard]] glm::i64vec3 cell_of(const glm::dvec3& p) const {
    glm::i64vec3 c;
    for (int a = 0; a < 3; ++a)
      c[a] = std::clamp<std::int64_t>(
          static_cast<std::int64_t>(std::floor((p[a] - lo_[a]) / cell_)), 0, dims_[a] - 1);
    return c;
  }
  [[nodiscard]] std::size_t index(const glm::i64vec3& c) const {
    return static_cast<std::size_t>((c.z * dims_[1] + c.y) * dims_[0] + c.x);
  }

  const std::vector<glm::dvec3>& x_;
  glm::dvec3 lo_{std::numeric_limits<double>::infinity()};
  glm::dvec3 hi_{-std::numeric_limits<double>::infinity()};
  double cell_ = 1.0;
  std::array<std::int64_t, 3> dims_{1, 1, 1};
  std::vector<std::uint32_t> start_, members_;
};

/// The corner of u whose side goes to w (invalid if none).
CornerId side_to(const Dlfl& mesh, VertexId u, VertexId w) {
  for (CornerId c : vertex_corners(mesh, u)) {
    if (!mesh.is_point_sphere(c) && mesh.vertex(mesh.next(c)) == w) return c;
  }
  return CornerId{};
}

struct Step {
  VertexId to;
  CornerId diagonal_from;  // valid: split this face from here to diagonal_to
  CornerId diagonal_to;
};

/// The cheapest path along edges from `from` to `to` (excluding `from`), each edge costing its
/// length plus twice its far end's distance from the blade's segment a-b, through unvisited
/// vertices within `radius` of b and never along the boundary; empty when there is none. It
/// carries the path across a mesh whose long triangles give no neighbour nearer the blade (a
/// decimated tube's strips run along its axis, so a cut around it finds no closer vertex).
std::vector<VertexId> detour(const Dlfl& mesh, const std::vector<glm::dvec3>& x, VertexId from,
                             VertexId to, const std::set<std::uint32_t>& visited,
                             const glm::dvec3& a, const glm::dvec3& b, double radius) {
  std::map<std::uint32_t, double> cost{{from.idx, 0.0}};
  std::map<std::uint32_t, std::uint32_t> came_from;
  using Entry = std::pair<double, std::uint32_t>;
  std::priority_queue<Entry, std::vector<Entry>, std::greater<>> open;
  open.push({0.0, from.idx});
  while (!open.empty()) {
    const auto [c_u, u] = open.top();
    open.pop();
    if (u == to.idx) break;
    if (c_u > cost[u]) continue;
    for (CornerId c : vertex_corners(mesh, VertexId(u))) {
      if (mesh.is_bounding(mesh.face(c)) || mesh.is_point_sphere(c)) continue;
      for (const CornerId side : {c, mesh.prev(c)}) {
        if (mesh.is_bounding(mesh.face(mesh.partner(side)))) continue;
        const VertexId w = side == c ? mesh.vertex(mesh.next(c)) : mesh.vertex(mesh.prev(c));
        if (visited.count(w.idx) != 0 || glm::length(x[w.idx] - b) > radius) continue;
        const double c_w =
            c_u + glm::length(x[w.idx] - x[u]) + 2.0 * point_segment_distance(x[w.idx], a, b);
        const auto known = cost.find(w.idx);
        if (known != cost.end() && known->second <= c_w) continue;
        cost[w.idx] = c_w;
        came_from[w.idx] = u;
        open.push({c_w, w.idx});
      }
    }
  }
  std::vector<VertexId> path;
  if (came_from.count(to.idx) == 0) return path;
  for (std::uint32_t v = to.idx; v != from.idx; v = came_from[v])
    path.push_back(VertexId(v));
  std::reverse(path.begin(), path.end());
  return path;
}

}  // namespace

CutResult cut_surface(SoftBody& body, std::span<const glm::dvec3> points,
                      const CutOptions& options) {
  if (points.size() < 2) throw CutError("cut: need at least two blade points");
  Dlfl& mesh = body.mesh_for_edit();
  const auto& x = body.positions();

  // ---- 1. The path (planned on the unchanged mesh) ----
  const VertexGrid grid(body);
  const VertexId start = grid.nearest(points.front());
  if (!start.valid()) throw CutError("cut: the solid has no surface to cut");
  std::vector<VertexId> path{start};
  std::vector<Step> steps;
  std::set<std::uint32_t> visited{start.idx};
  std::set<std::uint32_t> used_faces;
  bool reached_boundary = false;
  for (std::size_t seg = 1; seg < points.size() && !reached_boundary; ++seg) {
    const VertexId target = seg + 1 == points.size() ? grid.nearest(points[seg]) : VertexId{};
    const glm::dvec3 a = points[seg - 1], b = points[seg];
    for (int guard = 0; guard < 100000; ++guard) {
      const VertexId u = path.back();
      if (u == target) break;
      const double du = glm::length(x[u.idx] - b);
      double best_score = std::numeric_limits<double>::infinity();
      Step best{};
      for (CornerId c : vertex_corners(mesh, u)) {
        const FaceId f = mesh.face(c);
        if (mesh.is_bounding(f) || mesh.is_point_sphere(c) || used_faces.count(f.idx)) continue;
        const VertexId after = mesh.vertex(mesh.next(c));
        const VertexId before = mesh.vertex(mesh.prev(c));
        // Mean edge length of the face, for the sliver rule.
        double perimeter = 0.0;
        std::size_t corners = 0;
        for (CornerId k = mesh.next(c);; k = mesh.next(k)) {
          perimeter += glm::length(x[mesh.vertex(mesh.next(k)).idx] - x[mesh.vertex(k).idx]);
          ++corners;
          if (k == c) break;
        }
        const double mean_edge = perimeter / double(corners);
        for (CornerId k = mesh.next(c); k != c; k = mesh.next(k)) {
          const VertexId w = mesh.vertex(k);
          if (w == u || visited.count(w.idx)) continue;
          const double dw = glm::length(x[w.idx] - b);
          if (!(dw < du) && w != target) continue;
          const bool is_edge = (w == after || w == before);
          if (is_edge) {
            // Never along the boundary: both faces of the edge must be real.
            const CornerId s = w == after ? c : mesh.prev(c);
            if (mesh.is_bounding(mesh.face(mesh.partner(s)))) continue;
          } else {
            bool sliver = false;
            for (CornerId o = mesh.next(c); o != c; o = mesh.next(o)) {
              const VertexId ov = mesh.vertex(o);
              if (ov == w) continue;
              if (point_segment_distance(x[ov.idx], x[u.idx], x[w.idx]) <
                  options.sliver_fraction * mean_edge) {
                sliver = true;
              }
            }
            if (sliver) continue;
          }
          const double score = dw + 2.0 * point_segment_distance(x[w.idx], a, b);
          if (score < best_score) {
            best_score = score;
            best = Step{w, is_edge ? CornerId{} : c, is_edge ? CornerId{} : k};
          }
        }
      }
      if (!best.to.valid()) {
        // No neighbour comes closer: go round to the vertex nearest b when it is nearer than u.
        const VertexId nearest = target.valid() ? target : grid.nearest(b);
        if (!nearest.valid() || nearest == u || visited.count(nearest.idx) != 0 ||
            !(glm::length(x[nearest.idx] - b) < du)) {
          break;  // this segment is done
        }
        double longest_edge = 0.0;
        for (CornerId c : vertex_corners(mesh, u))
          longest_edge =
              std::max(longest_edge, glm::length(x[mesh.vertex(mesh.next(c)).idx] - x[u.idx]));
        const std::vector<VertexId> around =
            detour(mesh, x, u, nearest, visited, a, b, 2.0 * (du + longest_edge));
        if (around.empty()) break;
        for (const VertexId w : around) {
          steps.push_back(Step{w, CornerId{}, CornerId{}});
          path.push_back(w);
          visited.insert(w.idx);
          if (on_boundary(mesh, w)) {
            reached_boundary = true;
            break;
          }
        }
        if (reached_boundary) break;
        continue;
      }
      if (best.diagonal_from.valid()) used_faces.insert(mesh.face(best.diagonal_from).idx);
      steps.push_back(best);
      path.push_back(best.to);
      visited.insert(best.to.idx);
      if (on_boundary(mesh, best.to)) {
        reached_boundary = true;
        break;
      }
    }
  }
  const std::size_t k = path.size() - 1;
  CutResult result;
  result.starts_on_boundary = on_boundary(mesh, path.front());
  result.ends_on_boundary = on_boundary(mesh, path.back());
  std::vector<bool> opens(path.size(), false);
  for (std::size_t i = 0; i <= k; ++i) {
    opens[i] = (i > 0 && i < k) || (i == 0 && result.starts_on_boundary && k > 0) ||
               (i == k && result.ends_on_boundary && k > 0);
  }
  if (k == 0 || std::none_of(opens.begin(), opens.end(), [](bool o) { return o; })) {
    throw CutError("cut: the blade path covers " + std::to_string(k) +
                   " edge(s) and opens no vertex (too short or off the surface)");
  }
  if (k == 1 && result.starts_on_boundary && result.ends_on_boundary) {
    // A single chord edge between two boundary vertices: allowed (it separates a corner).
  }

  // ---- 2. Diagonals: split the faces the path crosses ----
  std::vector<EdgeId> inserted;
  InsertEdgeOptions no_check;
  no_check.check_label_orientation = false;
  for (const Step& s : steps) {
    if (!s.diagonal_from.valid()) continue;
    const InsertEdgeResult r = mesh.insert_edge(s.diagonal_from, s.diagonal_to, no_check);
    inserted.push_back(r.edge);
    ++result.split_faces;
  }

  // ---- 3. Open the incision: split every opening vertex along the path ----
  auto& xs = body.positions();
  std::vector<VertexId> right(path.begin(), path.end());  // right lip: the copy where opened
  for (std::size_t i = 0; i <= k; ++i) {
    if (!opens[i]) continue;
    const VertexId p = path[i];
    const CornerId s = i < k ? side_to(mesh, p, path[i + 1]) : CornerId{};
    const CornerId g = i > 0 ? side_to(mesh, p, path[i - 1]) : CornerId{};
    // Right-side fan corners c_1..c_m (their edges move to the copy).
    std::vector<CornerId> fan;
    CornerId c;
    if (i < k) {
      c = mesh.next(mesh.partner(s));
    } else {
      c = g;
      int guard = 0;
      do {
        c = mesh.rot_next(c);
      } while (!mesh.is_bounding(mesh.face(c)) && ++guard < 100000);
    }
    for (int guard = 0; guard < 100000; ++guard) {
      if (i > 0 && c == g) break;
      if (i == 0 && mesh.is_bounding(mesh.face(c))) break;
      fan.push_back(c);
      c = mesh.next(mesh.partner(c));
    }
    const CornerId stop = c;  // the corner left on the open side (g, or the boundary's)
    std::vector<CornerId> survivors;
    for (CornerId fc : fan)
      survivors.push_back(mesh.next(fc));
    for (CornerId fc : fan)
      mesh.delete_edge_pair(fc);

    const VertexId q = mesh.create_vertex(mesh.position(p));
    body.ensure_capacity();
    body.set_position(q, xs[p.idx]);
    body.set_velocity(q, body.velocity(p));
    body.set_anchored(q, body.anchored(p));
    body.set_rest_position(q, body.rest_position(p));
    right[i] = q;
    result.new_vertices.push_back(q);
    std::vector<EdgeId> local;
    const CornerId pc = mesh.rotation_corner(mesh.first_rotation(q));
    for (CornerId sv : survivors)
      local.push_back(mesh.insert_edge(pc, sv, no_check).edge);
    CornerId open_corner = pc;
    if (i < k) {
      const InsertEdgeResult r = mesh.insert_edge(pc, mesh.partner(s), no_check);
      local.push_back(r.edge);
      open_corner = r.side12;
    }
    if (i > 0 && !opens[i - 1]) {
      local.push_back(mesh.insert_edge(open_corner, mesh.next(g), no_check).edge);
    }
    // Labels went wherever the merges and splits took them: the faces around the new edges are
    // real faces except the open one (incision or boundary), found from its two lips.
    for (EdgeId e : local) {
      const CornerPair pr = mesh.primary_pair(e);
      mesh.set_bounding(mesh.face(pr.a), false);
      mesh.set_bounding(mesh.face(pr.b), false);
    }
    mesh.set_bounding(mesh.face(stop), true);
    mesh.set_bounding(mesh.face(open_corner), true);
    inserted.insert(inserted.end(), local.begin(), local.end());
  }

  // ---- 4. Labels: the incision (or the boundary it joined) is labelled, real faces are not ----
  for (EdgeId e : inserted) {
    if (!mesh.alive(e)) continue;
    const CornerPair pr = mesh.primary_pair(e);
    mesh.set_bounding(mesh.face(pr.a), false);
    mesh.set_bounding(mesh.face(pr.b), false);
  }
  for (std::size_t i = 1; i <= k; ++i) {
    const CornerId g = side_to(mesh, path[i], path[i - 1]);
    if (g.valid()) mesh.set_bounding(mesh.face(g), true);
    if (right[i - 1] != path[i - 1] || right[i] != path[i]) {
      const CornerId r = side_to(mesh, right[i - 1], right[i]);
      if (r.valid()) mesh.set_bounding(mesh.face(r), true);
    }
  }
  // ---- 5. Walls: an incision inside the surface closed down to the blade's tip ----
  if (!result.starts_on_boundary && !result.ends_on_boundary && k >= 2 &&
      options.blade_tips_m.size() == points.size()) {
    // Under each opened pair, as deep as the blade went at its nearest blade point.
    std::vector<glm::dvec3> floor, floor_rest;
    for (std::size_t i = 1; i < k; ++i) {
      const glm::dvec3& at = xs[path[i].idx];
      std::size_t nearest = 0;
      for (std::size_t s = 1; s < points.size(); ++s)
        if (glm::length(points[s] - at) < glm::length(points[nearest] - at)) nearest = s;
      const glm::dvec3 down = options.blade_tips_m[nearest] - points[nearest];
      floor.push_back(at + down);
      floor_rest.push_back(body.rest_position(path[i]) + down);
    }
    result.floor_vertices = close_incision(body, path, right, floor, floor_rest);
  }
  // Only the faces around the path and its copies changed: springs and masses update there.
  std::vector<VertexId> touched(path.begin(), path.end());
  touched.insert(touched.end(), result.new_vertices.begin(), result.new_vertices.end());
  touched.insert(touched.end(), result.floor_vertices.begin(), result.floor_vertices.end());
  body.refresh_topology_local(touched);
  result.path = std::move(path);
  return result;
}

bool ScalpelSweep::sample(const SoftBody& body, const SurfaceBvh& bvh,
                          const glm::dvec3& edge_from_m, const glm::dvec3& edge_to_m) {
  const SurfacePoint hit = bvh.ray(body, edge_from_m, edge_to_m);
  if (!hit.found) return false;
  points_.push_back(hit.point_m);
  return true;
}

CutResult ScalpelSweep::finish(SoftBody& body, const CutOptions& options) {
  std::vector<glm::dvec3> pts;
  pts.swap(points_);
  if (pts.size() < 2) throw CutError("scalpel: the blade touched the surface fewer than twice");
  return cut_surface(body, pts, options);
}

}  // namespace bisturi::sim
