#include "bisturi/scene/measure/plane_cut.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <string>

#include <glm/geometric.hpp>

#include "bisturi/scene/errors.h"

namespace bisturi {
namespace {

using Vec3 = glm::dvec3;

/// The one sign rule of every decision: distance 0 counts as positive.
struct SidedPlane {
  Vec3 normal;
  double offset;
  [[nodiscard]] double distance(const Vec3& p) const {
    return normal.x * p.x + normal.y * p.y + normal.z * p.z - offset;
  }
  [[nodiscard]] bool positive(const Vec3& p) const { return distance(p) >= 0.0; }
};

SidedPlane make_sided(const Plane& plane, Plane& normalized) {
  const double len = glm::length(plane.normal);
  if (!(len > 0.0) || !std::isfinite(len) || !std::isfinite(plane.point.x) ||
      !std::isfinite(plane.point.y) || !std::isfinite(plane.point.z)) {
    throw InputError("plane cut: the plane needs a finite point and a non-zero finite normal");
  }
  normalized.point = plane.point;
  normalized.normal = plane.normal / len;
  return {normalized.normal, glm::dot(normalized.normal, plane.point)};
}

/// Area-weighted normal at the vertex of corner c, over the non-labelled faces of its rotation.
Vec3 vertex_normal(const Dlfl& m, CornerId c) {
  const Vec3& p = m.position(m.vertex(c));
  Vec3 sum(0.0);
  CornerId r = c;
  for (std::size_t guard = 0; guard < 4096; ++guard) {
    if (!m.is_bounding(m.face(r)) && !m.is_point_sphere(r)) {
      sum += glm::cross(m.position(m.vertex(m.next(r))) - p, m.position(m.vertex(m.prev(r))) - p);
    }
    r = m.rot_next(r);
    if (r == c || !r.valid()) break;
  }
  const double len = glm::length(sum);
  return len > 0.0 ? sum / len : Vec3(0.0);
}

class Walker {
 public:
  Walker(const Dlfl& mesh, const SidedPlane& plane, const CutOptions& options,
         std::vector<CornerId>& seeds, PlaneCut& out)
      : m_(mesh), plane_(plane), options_(options), seeds_(seeds), out_(out) {
    std::sort(seeds_.begin(), seeds_.end());
    seeds_.erase(std::unique(seeds_.begin(), seeds_.end()), seeds_.end());
    visited_.assign(seeds_.size(), 0);
  }

  void run() {
    for (std::size_t i = 0; i < seeds_.size(); ++i) {
      if (visited_[i] == 0) walk(seeds_[i]);
    }
  }

 private:
  [[nodiscard]] bool positive(CornerId c) const {
    return plane_.positive(m_.position(m_.vertex(c)));
  }

  /// Marks side s (a seed: every entering side of a crossing edge is one); false if already.
  bool mark(CornerId s) {
    const auto it = std::lower_bound(seeds_.begin(), seeds_.end(), s);
    if (it == seeds_.end() || *it != s) return true;  // not indexed: cannot repeat a seed walk
    auto& v = visited_[static_cast<std::size_t>(it - seeds_.begin())];
    if (v != 0) return false;
    v = 1;
    return true;
  }

  /// In s's face, the first side after s (by next) that leaves the positive half-space.
  [[nodiscard]] CornerId exit_side(CornerId s) const {
    CornerId c = m_.next(s);
    bool here = true;  // vertex(next(s)) is positive
    for (std::size_t guard = 0; guard < 1u << 20 && c != s; ++guard) {
      const CornerId n = m_.next(c);
      const bool there = positive(n);
      if (here && !there) return c;
      here = there;
      c = n;
    }
    return CornerId{};
  }

  /// In p's face, the first side before p (by prev) that enters the positive half-space.
  [[nodiscard]] CornerId entry_side(CornerId p) const {
    CornerId c = m_.prev(p);
    bool there = positive(p);  // the end of side c is vertex(p), positive
    for (std::size_t guard = 0; guard < 1u << 20 && c != p; ++guard) {
      const bool here = positive(c);
      if (!here && there) return c;
      there = here;
      c = m_.prev(c);
    }
    return CornerId{};
  }

  void add_point(CornerId s, CutLoop& loop) const {
    const Vec3& a = m_.position(m_.vertex(s));
    const Vec3& b = m_.position(m_.vertex(m_.next(s)));
    const double da = plane_.distance(a), db = plane_.distance(b);
    const double t = db == 0.0 ? 1.0 : da / (da - db);
    const Vec3 p = db == 0.0 ? b : a + t * (b - a);
    loop.points.push_back(p);
    loop.edges.push_back(m_.edge(s));
    if (!options_.surface_points) return;
    Vec3 q = p;
    if (t > 0.0 && t < 1.0) {
      const Vec3 na = vertex_normal(m_, s), nb = vertex_normal(m_, m_.next(s));
      const double lift = 0.5 * t * (1.0 - t) * glm::dot(nb - na, b - a);
      Vec3 n = (1.0 - t) * na + t * nb;
      const double len = glm::length(n);
      if (len > 0.0) {
        n /= len;
        const Vec3 in_plane = n - glm::dot(n, plane_.normal) * plane_.normal;
        const double n2 = glm::dot(in_plane, in_plane);
        // A surface nearly parallel to the plane: the in-plane move would blow up; keep p.
        if (n2 > 0.1) q = p + in_plane * (lift / n2);
      }
    }
    loop.surface_points.push_back(q);
  }

  void walk(CornerId seed) {
    CutLoop loop;
    mark(seed);
    // Forward from the seed until the walk closes or reaches a labelled face.
    CornerId cur = seed;
    bool closed = false;
    for (;;) {
      add_point(cur, loop);
      if (m_.is_bounding(m_.face(cur))) break;
      const CornerId x = exit_side(cur);
      if (!x.valid()) break;
      ++loop.faces_touched;
      const CornerId next = m_.partner(x);
      if (!next.valid()) break;
      if (next == seed) {
        closed = true;
        break;
      }
      if (!mark(next)) break;  // a loop already walked (only non-manifold input gets here)
      cur = next;
    }
    if (!closed) {
      // Backward from the seed to the other boundary; those points go first, reversed.
      CutLoop back;
      cur = seed;
      for (;;) {
        const CornerId p = m_.partner(cur);
        if (!p.valid() || m_.is_bounding(m_.face(p))) break;
        const CornerId e = entry_side(p);
        if (!e.valid()) break;
        ++loop.faces_touched;
        if (!mark(e)) break;
        add_point(e, back);
        cur = e;
      }
      if (!back.points.empty()) {
        std::reverse(back.points.begin(), back.points.end());
        std::reverse(back.edges.begin(), back.edges.end());
        std::reverse(back.surface_points.begin(), back.surface_points.end());
        back.points.insert(back.points.end(), loop.points.begin(), loop.points.end());
        back.edges.insert(back.edges.end(), loop.edges.begin(), loop.edges.end());
        back.surface_points.insert(back.surface_points.end(), loop.surface_points.begin(),
                                   loop.surface_points.end());
        loop.points = std::move(back.points);
        loop.edges = std::move(back.edges);
        loop.surface_points = std::move(back.surface_points);
      }
    }
    loop.closed = closed;
    out_.faces_touched += loop.faces_touched;
    if (!finish(loop)) return;
    std::vector<double> lengths;
    lengths.reserve(loop.edges.size());
    for (const EdgeId e : loop.edges) {
      const CornerPair p = m_.primary_pair(e);
      lengths.push_back(glm::distance(m_.position(m_.vertex(p.a)), m_.position(m_.vertex(p.b))));
    }
    const auto mid = lengths.begin() + static_cast<std::ptrdiff_t>(lengths.size() / 2);
    std::nth_element(lengths.begin(), mid, lengths.end());
    loop.edge_length = *mid;
    out_.loops.push_back(std::move(loop));
  }

  /// Drops repeated consecutive points; false when the loop collapsed.
  static bool finish(CutLoop& loop) {
    std::size_t kept = 0;
    const std::size_t n = loop.points.size();
    const bool surface = !loop.surface_points.empty();
    for (std::size_t i = 0; i < n; ++i) {
      if (kept > 0 && loop.points[i] == loop.points[kept - 1]) continue;
      loop.points[kept] = loop.points[i];
      loop.edges[kept] = loop.edges[i];
      if (surface) loop.surface_points[kept] = loop.surface_points[i];
      ++kept;
    }
    if (loop.closed && kept > 1 && loop.points[kept - 1] == loop.points[0]) --kept;
    loop.points.resize(kept);
    loop.edges.resize(kept);
    if (surface) loop.surface_points.resize(kept);
    return kept >= (loop.closed ? 3u : 2u);
  }

  const Dlfl& m_;
  const SidedPlane& plane_;
  const CutOptions& options_;
  std::vector<CornerId>& seeds_;
  std::vector<std::uint8_t> visited_;
  PlaneCut& out_;
};

/// The entering sides (negative -> positive) of edge e, one per corner pair.
template <class F>
void entering_sides(const Dlfl& m, EdgeId e, bool first_positive, F&& emit) {
  const CornerPair p = m.primary_pair(e);
  emit(first_positive ? p.b : p.a);
  if (m.edge_pair_count(e) > 1) {
    const std::vector<CornerPair> pairs = m.edge_pairs(e);
    for (std::size_t i = 1; i < pairs.size(); ++i) {
      // Extra pairs may run either way: pick the side that starts on the negative vertex.
      const CornerPair& q = pairs[i];
      const bool a_positive = m.vertex(q.a) == m.vertex(p.a) ? first_positive : !first_positive;
      emit(a_positive ? q.b : q.a);
    }
  }
}

float round_down(double v) {
  auto f = static_cast<float>(v);
  if (double(f) > v) f = std::nextafter(f, -std::numeric_limits<float>::infinity());
  return f;
}
float round_up(double v) {
  auto f = static_cast<float>(v);
  if (double(f) < v) f = std::nextafter(f, std::numeric_limits<float>::infinity());
  return f;
}

}  // namespace

CutIndex::CutIndex(const Dlfl& mesh, std::size_t leaf_size) : mesh_(&mesh) {
  leaf_size = std::max<std::size_t>(1, leaf_size);
  const auto& records = mesh.edge_records();
  const auto& pos = mesh.positions();
  std::vector<std::uint32_t> items;
  items.reserve(records.size());
  std::vector<std::array<std::uint32_t, 2>> ends(records.size());
  std::vector<Vec3> mid(records.size());
  for (std::size_t e = 0; e < records.size(); ++e) {
    const CornerPair& p = records[e];
    if (!p.a.valid()) continue;
    const std::uint32_t v0 = mesh.vertex(p.a).idx, v1 = mesh.vertex(p.b).idx;
    ends[e] = {v0, v1};
    mid[e] = 0.5 * (pos[v0] + pos[v1]);
    items.push_back(static_cast<std::uint32_t>(e));
  }
  if (items.size() >= std::numeric_limits<std::uint32_t>::max() / 2) {
    throw InputError("plane cut: too many edges for the index");
  }
  struct Task {
    std::uint32_t node, begin, end;
  };
  std::vector<Task> stack;
  nodes_.reserve(2 * items.size() / leaf_size + 2);
  nodes_.push_back({});
  stack.push_back({0, 0, static_cast<std::uint32_t>(items.size())});
  while (!stack.empty()) {
    const Task task = stack.back();
    stack.pop_back();
    Vec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
    Vec3 clo = lo, chi = hi;
    for (std::uint32_t i = task.begin; i < task.end; ++i) {
      const auto& en = ends[items[i]];
      const Vec3& a = pos[en[0]];
      const Vec3& b = pos[en[1]];
      lo = glm::min(lo, glm::min(a, b));
      hi = glm::max(hi, glm::max(a, b));
      clo = glm::min(clo, mid[items[i]]);
      chi = glm::max(chi, mid[items[i]]);
    }
    Node& node = nodes_[task.node];
    for (int a = 0; a < 3; ++a) {
      node.lo[a] = task.end > task.begin ? round_down(lo[a]) : 0.0f;
      node.hi[a] = task.end > task.begin ? round_up(hi[a]) : -1.0f;
    }
    const std::uint32_t n = task.end - task.begin;
    const Vec3 extent = chi - clo;
    if (n <= leaf_size || !(std::max({extent.x, extent.y, extent.z}) > 0.0)) {
      node.first = task.begin;
      node.count = n;  // 0 only for an empty mesh's root, which cut() never reads
      continue;
    }
    const int axis =
        extent.x >= extent.y && extent.x >= extent.z ? 0 : (extent.y >= extent.z ? 1 : 2);
    const std::uint32_t half = task.begin + n / 2;
    std::nth_element(items.begin() + task.begin, items.begin() + half, items.begin() + task.end,
                     [&](std::uint32_t x, std::uint32_t y) { return mid[x][axis] < mid[y][axis]; });
    const auto left = static_cast<std::uint32_t>(nodes_.size());
    node.first = left;
    node.count = 0;
    nodes_.push_back({});
    nodes_.push_back({});
    stack.push_back({left, task.begin, half});
    stack.push_back({left + 1, half, task.end});
  }
  edges_.reserve(items.size());
  ends_.reserve(2 * items.size());
  for (const std::uint32_t e : items) {
    edges_.push_back(EdgeId{e});
    ends_.push_back(ends[e][0]);
    ends_.push_back(ends[e][1]);
  }
}

std::size_t CutIndex::memory_bytes() const {
  return nodes_.capacity() * sizeof(Node) + edges_.capacity() * sizeof(EdgeId) +
         ends_.capacity() * sizeof(std::uint32_t);
}

PlaneCut CutIndex::cut(const Plane& plane, const CutOptions& options) const {
  PlaneCut out;
  const SidedPlane sp = make_sided(plane, out.plane);
  std::vector<CornerId> seeds;
  if (edges_.empty()) return out;
  const auto& pos = mesh_->positions();
  std::vector<std::uint32_t> stack;
  stack.push_back(0);
  const Vec3 an = glm::abs(sp.normal);
  while (!stack.empty()) {
    const Node& node = nodes_[stack.back()];
    stack.pop_back();
    const Vec3 lo(node.lo[0], node.lo[1], node.lo[2]), hi(node.hi[0], node.hi[1], node.hi[2]);
    const Vec3 centre = 0.5 * (lo + hi), half = 0.5 * (hi - lo);
    const double d = sp.distance(centre);
    const double r = glm::dot(an, half) * (1.0 + 1e-12) + 1e-300;
    // All positive (min >= 0) or all negative (max < 0): no edge inside can cross.
    if (d - r > 0.0 || d + r < 0.0) continue;
    ++out.nodes_visited;
    if (node.count == 0) {
      stack.push_back(node.first);
      stack.push_back(node.first + 1);
      continue;
    }
    out.edges_tested += node.count;
    for (std::uint32_t i = node.first; i < node.first + node.count; ++i) {
      const bool p0 = sp.positive(pos[ends_[2 * std::size_t{i}]]);
      const bool p1 = sp.positive(pos[ends_[2 * std::size_t{i} + 1]]);
      if (p0 == p1) continue;
      ++out.crossing_edges;
      entering_sides(*mesh_, edges_[i], p0, [&](CornerId s) { seeds.push_back(s); });
    }
  }
  Walker(*mesh_, sp, options, seeds, out).run();
  return out;
}

PlaneCut cut_plane_brute_force(const Dlfl& mesh, const Plane& plane, const CutOptions& options) {
  PlaneCut out;
  const SidedPlane sp = make_sided(plane, out.plane);
  std::vector<CornerId> seeds;
  const auto& records = mesh.edge_records();
  for (std::size_t e = 0; e < records.size(); ++e) {
    const CornerPair& p = records[e];
    if (!p.a.valid()) continue;
    ++out.edges_tested;
    const bool p0 = sp.positive(mesh.position(mesh.vertex(p.a)));
    const bool p1 = sp.positive(mesh.position(mesh.vertex(p.b)));
    if (p0 == p1) continue;
    ++out.crossing_edges;
    entering_sides(mesh, EdgeId{static_cast<std::uint32_t>(e)}, p0,
                   [&](CornerId s) { seeds.push_back(s); });
  }
  Walker(mesh, sp, options, seeds, out).run();
  return out;
}

}  // namespace bisturi
