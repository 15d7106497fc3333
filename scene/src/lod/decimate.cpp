// QEM edge-collapse decimation through the DLFL operators (see decimate.h for what is kept).
//
// Candidates sit in a min-heap keyed by their quadric error, with lazy invalidation: each entry
// carries the versions of its two vertices, and a vertex's version changes whenever its quadric,
// position or neighbourhood does, so stale entries are dropped when popped. A collapse that is
// refused marks its two vertices; when a later collapse changes the neighbourhood of a marked
// vertex, that vertex's edges are queued again.

#include "bisturi/scene/lod/decimate.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <numbers>
#include <queue>
#include <vector>

#include <glm/geometric.hpp>

namespace bisturi::lod {

namespace {

using Vec3 = Dlfl::Vec3;

/// A triangle's shape: 4 sqrt(3) area over its squared edges' sum, 1 equilateral, 0 degenerate
/// (about 0.17 for a sliver ten times as long as wide). `twice_area`: |(b - a) x (c - a)|.
double triangle_quality(const Vec3& a, const Vec3& b, const Vec3& c, double twice_area) {
  const double edges = glm::dot(b - a, b - a) + glm::dot(c - b, c - b) + glm::dot(a - c, a - c);
  return edges > 0.0 ? 2.0 * std::numbers::sqrt3 * twice_area / edges : 0.0;
}

/// Symmetric 4x4 quadric: a00 a01 a02 a03 a11 a12 a13 a22 a23 a33.
struct Quadric {
  double q[10] = {0, 0, 0, 0, 0, 0, 0, 0, 0, 0};

  static Quadric plane(const Vec3& n, double d) {
    Quadric k;
    k.q[0] = n.x * n.x;
    k.q[1] = n.x * n.y;
    k.q[2] = n.x * n.z;
    k.q[3] = n.x * d;
    k.q[4] = n.y * n.y;
    k.q[5] = n.y * n.z;
    k.q[6] = n.y * d;
    k.q[7] = n.z * n.z;
    k.q[8] = n.z * d;
    k.q[9] = d * d;
    return k;
  }
  Quadric& operator+=(const Quadric& o) {
    for (int i = 0; i < 10; ++i)
      q[i] += o.q[i];
    return *this;
  }
  [[nodiscard]] double eval(const Vec3& p) const {
    const double x = p.x, y = p.y, z = p.z;
    return q[0] * x * x + 2 * q[1] * x * y + 2 * q[2] * x * z + 2 * q[3] * x + q[4] * y * y +
           2 * q[5] * y * z + 2 * q[6] * y + q[7] * z * z + 2 * q[8] * z + q[9];
  }
  /// The minimiser of eval when the 3x3 part is well conditioned.
  bool optimum(Vec3& out) const {
    const double a = q[0], b = q[1], c = q[2], d = q[4], e = q[5], f = q[7];
    // Cofactors of the symmetric matrix [a b c; b d e; c e f].
    const double c00 = d * f - e * e, c01 = c * e - b * f, c02 = b * e - c * d;
    const double c11 = a * f - c * c, c12 = b * c - a * e, c22 = a * d - b * b;
    const double det = a * c00 + b * c01 + c * c02;
    const double trace = a + d + f;
    if (!(trace > 0.0) || std::abs(det) <= 1e-6 * trace * trace * trace) return false;
    const double inv = 1.0 / det;
    const double rx = -q[3], ry = -q[6], rz = -q[8];
    out = Vec3((c00 * rx + c01 * ry + c02 * rz) * inv, (c01 * rx + c11 * ry + c12 * rz) * inv,
               (c02 * rx + c12 * ry + c22 * rz) * inv);
    return std::isfinite(out.x) && std::isfinite(out.y) && std::isfinite(out.z);
  }
};

struct Candidate {
  double cost;
  std::uint32_t a, b;    // the edge's ends
  std::uint32_t va, vb;  // their versions when queued
  Vec3 p;                // where the kept vertex goes
};

/// What the heap moves around: the key and where the candidate is stored (16 bytes, so sifting
/// through a heap of a million entries touches a third of the memory a whole candidate would).
struct HeapEntry {
  double cost;
  std::uint32_t slot;
  bool operator>(const HeapEntry& o) const { return cost > o.cost; }
};

constexpr std::uint8_t kFixed = 1;
constexpr std::uint8_t kBoundary = 2;  // on a labelled face (implies fixed)

class Decimator {
 public:
  Decimator(Dlfl& mesh, const DecimateOptions& options) : mesh_(mesh), opt_(options) {}

  DecimateStats run();

 private:
  bool face_is_triangle(FaceId f) const {
    const CornerId c = mesh_.first_corner(f);
    const CornerId n = mesh_.next(c);
    return n != c && mesh_.next(n) != c && mesh_.next(mesh_.next(n)) == c;
  }
  bool labelled(FaceId f) const { return mesh_.bounding_labels()[f.idx] != 0; }

  /// Every neighbour of x over all its rotations (each edge side leaving x once).
  void neighbours(VertexId x, std::vector<std::uint32_t>& out) const {
    out.clear();
    for (RotationId r = mesh_.first_rotation(x); r.valid(); r = mesh_.next_rotation(r)) {
      const CornerId start = mesh_.rotation_corner(r);
      CornerId c = start;
      do {
        if (!mesh_.is_point_sphere(c)) out.push_back(mesh_.vertex(mesh_.next(c)).idx);
        c = mesh_.rot_next(c);
      } while (c != start);
    }
  }
  std::size_t valence(std::uint32_t x) {
    neighbours(VertexId(x), scratch_);
    return scratch_.size();
  }

  void classify();
  void init_quadrics();
  void push_edges_of(std::uint32_t x, const std::vector<std::uint32_t>* skip_lower);
  bool make_candidate(std::uint32_t a, std::uint32_t b, Candidate& out) const;
  /// 0: ok, 1: topology, 2: geometry.
  int check(std::uint32_t keep, std::uint32_t remove, const Vec3& p);
  void collapse(std::uint32_t keep, std::uint32_t remove, const Vec3& p);

  Dlfl& mesh_;
  const DecimateOptions& opt_;
  std::vector<std::uint8_t> flags_;
  std::vector<Quadric> quadric_;
  std::vector<std::uint32_t> version_;
  std::vector<std::uint8_t> rejected_;
  void push(const Candidate& c) {
    std::uint32_t slot;
    if (!free_slots_.empty()) {
      slot = free_slots_.back();
      free_slots_.pop_back();
      slots_[slot] = c;
    } else {
      slot = static_cast<std::uint32_t>(slots_.size());
      slots_.push_back(c);
    }
    heap_.push({c.cost, slot});
  }
  Candidate pop() {
    const std::uint32_t slot = heap_.top().slot;
    heap_.pop();
    free_slots_.push_back(slot);
    return slots_[slot];
  }

  std::priority_queue<HeapEntry, std::vector<HeapEntry>, std::greater<>> heap_;
  std::vector<Candidate> slots_;
  std::vector<std::uint32_t> free_slots_;
  std::vector<std::uint32_t> ring_keep_, ring_remove_, scratch_, touched_;
  std::vector<CornerId> corners_;
  DecimateStats stats_;
};

void Decimator::classify() {
  const std::size_t n = mesh_.vertex_capacity();
  flags_.assign(n, 0);
  for (std::uint32_t v = 0; v < n; ++v) {
    const VertexId x(v);
    if (!mesh_.alive(x)) continue;
    const RotationId r = mesh_.first_rotation(x);
    std::uint8_t f = 0;
    if (mesh_.next_rotation(r).valid()) f = kFixed;
    const CornerId start = mesh_.rotation_corner(r);
    if (mesh_.is_point_sphere(start)) f = kFixed;
    for (RotationId q = r; q.valid(); q = mesh_.next_rotation(q)) {
      const CornerId s = mesh_.rotation_corner(q);
      CornerId c = s;
      do {
        const FaceId face = mesh_.face(c);
        if (labelled(face)) {
          f = kFixed | kBoundary;
        } else if (!face_is_triangle(face)) {
          f |= kFixed;
        }
        c = mesh_.rot_next(c);
      } while (c != s);
    }
    flags_[v] = f;
    if (f & kFixed) ++stats_.fixed_vertices;
  }
}

void Decimator::init_quadrics() {
  quadric_.assign(mesh_.vertex_capacity(), Quadric{});
  for (std::uint32_t fi = 0; fi < mesh_.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh_.alive(f) || labelled(f)) continue;
    const CornerId start = mesh_.first_corner(f);
    if (mesh_.next(start) == start || mesh_.next(mesh_.next(start)) == start) continue;
    // Newell normal and centroid: the plane of a triangle, a best fit for larger polygons.
    Vec3 normal(0.0), centroid(0.0);
    std::size_t count = 0;
    CornerId c = start;
    do {
      const Vec3& p = mesh_.position(mesh_.vertex(c));
      const Vec3& q = mesh_.position(mesh_.vertex(mesh_.next(c)));
      normal += glm::cross(p, q);
      centroid += p;
      ++count;
      c = mesh_.next(c);
    } while (c != start);
    const double len = glm::length(normal);
    if (!(len > 0.0)) continue;
    normal /= len;
    centroid /= static_cast<double>(count);
    const Quadric k = Quadric::plane(normal, -glm::dot(normal, centroid));
    c = start;
    do {
      quadric_[mesh_.vertex(c).idx] += k;
      c = mesh_.next(c);
    } while (c != start);
  }
}

bool Decimator::make_candidate(std::uint32_t a, std::uint32_t b, Candidate& out) const {
  const bool fa = flags_[a] & kFixed, fb = flags_[b] & kFixed;
  if (fa && fb) return false;
  Quadric q = quadric_[a];
  q += quadric_[b];
  const Vec3& pa = mesh_.position(VertexId(a));
  const Vec3& pb = mesh_.position(VertexId(b));
  Vec3 p;
  if (fa) {
    p = pa;
  } else if (fb) {
    p = pb;
  } else {
    bool ok = q.optimum(p);
    // An optimum far off the edge comes from a nearly singular system: do not trust it.
    if (ok) {
      const Vec3 mid = 0.5 * (pa + pb);
      const Vec3 d = pb - pa;
      ok = glm::dot(p - mid, p - mid) <= 4.0 * glm::dot(d, d);
    }
    if (!ok) {
      // Best point on the edge: minimise the quadratic q(pa + t (pb - pa)) over t in [0, 1].
      const double f0 = q.eval(pa), f1 = q.eval(pb), fm = q.eval(0.5 * (pa + pb));
      // f(t) = f0 + s t + w t^2 through f(0), f(1/2), f(1).
      const double w = 2.0 * (f1 + f0 - 2.0 * fm);
      const double s = f1 - f0 - w;
      double t = f0 <= f1 ? 0.0 : 1.0;
      if (w > 0.0) t = std::clamp(-s / (2.0 * w), 0.0, 1.0);
      p = pa + t * (pb - pa);
    }
  }
  out.cost = std::max(0.0, q.eval(p));
  out.a = a;
  out.b = b;
  out.va = version_[a];
  out.vb = version_[b];
  out.p = p;
  return true;
}

void Decimator::push_edges_of(std::uint32_t x, const std::vector<std::uint32_t>* skip_lower) {
  std::vector<std::uint32_t> nb;
  neighbours(VertexId(x), nb);
  for (const std::uint32_t y : nb) {
    // An edge between two re-queued vertices is queued once, from its lower end.
    if (skip_lower != nullptr && y < x &&
        std::find(skip_lower->begin(), skip_lower->end(), y) != skip_lower->end()) {
      continue;
    }
    Candidate cand;
    if (make_candidate(x, y, cand)) push(cand);
  }
}

int Decimator::check(std::uint32_t keep, std::uint32_t remove, const Vec3& p) {
  // ---- topology: the link condition ----
  neighbours(VertexId(keep), ring_keep_);
  // The ring of `remove` in rotation order, with its corners (remove is free: one rotation).
  corners_.clear();
  ring_remove_.clear();
  {
    const CornerId start = mesh_.rotation_corner(mesh_.first_rotation(VertexId(remove)));
    CornerId c = start;
    do {
      corners_.push_back(c);
      ring_remove_.push_back(mesh_.vertex(mesh_.next(c)).idx);
      c = mesh_.rot_next(c);
    } while (c != start);
  }
  const std::size_t k = ring_remove_.size();
  if (k < 3) return 1;
  // The two opposite vertices: the third corners of the triangles on the edge.
  std::uint32_t opposite[2];
  int n_opposite = 0;
  for (const CornerId c : corners_) {
    const VertexId a = mesh_.vertex(mesh_.next(c));
    const VertexId b = mesh_.vertex(mesh_.next(mesh_.next(c)));
    if (a.idx == keep && n_opposite < 2) opposite[n_opposite++] = b.idx;
    if (b.idx == keep && n_opposite < 2) opposite[n_opposite++] = a.idx;
  }
  if (n_opposite != 2 || opposite[0] == opposite[1]) return 1;
  std::size_t common = 0;
  for (const std::uint32_t w : ring_remove_) {
    if (w == keep) continue;
    if (std::find(ring_keep_.begin(), ring_keep_.end(), w) != ring_keep_.end()) {
      if (w != opposite[0] && w != opposite[1]) return 1;
      ++common;
    }
  }
  if (common != 2) return 1;
  for (const std::uint32_t o : opposite) {
    const std::size_t need = (flags_[o] & kBoundary) ? 3 : 4;
    if (valence(o) < need) return 1;
  }
  const std::size_t keep_after = ring_keep_.size() + k - 4;
  if (keep_after < ((flags_[keep] & kBoundary) ? 2u : 3u)) return 1;

  // ---- geometry: no face may flip, fold or collapse, nor (with a quality bound) thin ----
  const double cos_min = opt_.min_normal_cosine;
  // The thinnest of the faces the collapse moves, before and after it.
  double thinnest_before = HUGE_VAL, thinnest_after = HUGE_VAL;
  auto bad = [&](const Vec3& o, const Vec3& a, const Vec3& b) {
    const Vec3 n0 = glm::cross(a - o, b - o);
    const Vec3 n1 = glm::cross(a - p, b - p);
    const double l0 = glm::length(n0);
    const double l1 = glm::length(n1);
    if (!(l0 > 0.0)) return false;  // already degenerate: nothing to judge
    if (!(l1 > 1e-6 * l0)) return true;
    if (opt_.min_triangle_quality > 0.0) {
      thinnest_before = std::min(thinnest_before, triangle_quality(o, a, b, l0));
      thinnest_after = std::min(thinnest_after, triangle_quality(p, a, b, l1));
    }
    return glm::dot(n0, n1) < cos_min * l0 * l1;
  };
  const Vec3 pr = mesh_.position(VertexId(remove));
  for (const CornerId c : corners_) {
    const VertexId a = mesh_.vertex(mesh_.next(c));
    const VertexId b = mesh_.vertex(mesh_.next(mesh_.next(c)));
    if (a.idx == keep || b.idx == keep) continue;
    if (bad(pr, mesh_.position(a), mesh_.position(b))) return 2;
  }
  if (!(flags_[keep] & kFixed)) {
    const Vec3 pk = mesh_.position(VertexId(keep));
    const CornerId start = mesh_.rotation_corner(mesh_.first_rotation(VertexId(keep)));
    CornerId c = start;
    do {
      const VertexId a = mesh_.vertex(mesh_.next(c));
      const VertexId b = mesh_.vertex(mesh_.next(mesh_.next(c)));
      if (a.idx != remove && b.idx != remove && bad(pk, mesh_.position(a), mesh_.position(b))) {
        return 2;
      }
      c = mesh_.rot_next(c);
    } while (c != start);
  }
  // A face thinner than the bound only where one was thinner before: the surface of a marching
  // cubes extraction starts with slivers, and a collapse that thins none further may go on.
  if (thinnest_after < opt_.min_triangle_quality && thinnest_after < thinnest_before) return 2;
  return 0;
}

void Decimator::collapse(std::uint32_t keep, std::uint32_t remove, const Vec3& p) {
  // corners_ holds the corners of `remove` (from check()); their edges go one by one. The
  // triangles merge into one polygon around `remove`; the last deletion leaves it a point sphere.
  std::vector<EdgeId> edges;
  edges.reserve(corners_.size());
  for (const CornerId c : corners_)
    edges.push_back(mesh_.edge(c));
  DeleteEdgeResult last{};
  for (const EdgeId e : edges)
    last = mesh_.delete_edge(e);
  mesh_.delete_vertex(VertexId(remove));
  // The hole: find the corner of `keep` and fan-triangulate from it.
  const FaceId hole = last.face_a;
  CornerId x = mesh_.first_corner(hole);
  while (mesh_.vertex(x).idx != keep)
    x = mesh_.next(x);
  while (mesh_.next(mesh_.next(mesh_.next(x))) != x) {
    x = mesh_.insert_edge(x, mesh_.next(mesh_.next(x))).side12;
  }
  mesh_.set_position(VertexId(keep), p);
  quadric_[keep] += quadric_[remove];
  ++version_[keep];
  ++version_[remove];

  // Queue the edges of `keep`, and again those of refused neighbours whose ring just changed.
  neighbours(VertexId(keep), touched_);
  std::vector<std::uint32_t> requeue{keep};
  for (const std::uint32_t w : touched_) {
    if (rejected_[w]) {
      rejected_[w] = 0;
      ++version_[w];
      requeue.push_back(w);
    }
  }
  for (const std::uint32_t w : requeue)
    push_edges_of(w, requeue.size() > 1 ? &requeue : nullptr);
}

DecimateStats Decimator::run() {
  stats_.initial_faces = polygon_face_count(mesh_);
  std::size_t faces = stats_.initial_faces;
  classify();
  init_quadrics();
  version_.assign(mesh_.vertex_capacity(), 0);
  rejected_.assign(mesh_.vertex_capacity(), 0);
  {
    std::vector<HeapEntry> initial;
    initial.reserve(mesh_.num_edges());
    slots_.reserve(mesh_.num_edges());
    for (std::uint32_t e = 0; e < mesh_.edge_capacity(); ++e) {
      if (!mesh_.alive(EdgeId(e))) continue;
      const auto [a, b] = std::pair(mesh_.vertex(mesh_.primary_pair(EdgeId(e)).a),
                                    mesh_.vertex(mesh_.primary_pair(EdgeId(e)).b));
      Candidate cand;
      if (make_candidate(a.idx, b.idx, cand)) {
        initial.push_back({cand.cost, static_cast<std::uint32_t>(slots_.size())});
        slots_.push_back(cand);
      }
    }
    heap_ = decltype(heap_)(std::greater<>(), std::move(initial));
  }

  const std::size_t target = opt_.target_faces;
  const std::size_t total =
      target > 0 ? (faces > target ? (faces - target + 1) / 2 : 0) : faces / 2;
  const std::size_t step = std::max<std::size_t>(1, total / 100);
  const double max_cost = opt_.max_error * opt_.max_error;

  while (true) {
    if (target > 0 && faces <= target) {
      stats_.reached_target = true;
      break;
    }
    if (heap_.empty()) break;
    const Candidate cand = pop();
    if (!mesh_.alive(VertexId(cand.a)) || !mesh_.alive(VertexId(cand.b)) ||
        version_[cand.a] != cand.va || version_[cand.b] != cand.vb) {
      continue;
    }
    if (cand.cost > max_cost) {
      stats_.stopped_by_error = true;
      break;
    }
    std::uint32_t keep = cand.a, remove = cand.b;
    // A fixed end must be the one kept; otherwise keep the busier end, so fewer edges are
    // deleted and inserted.
    const bool remove_fixed = (flags_[remove] & kFixed) != 0;
    const bool keep_fixed = (flags_[keep] & kFixed) != 0;
    if (remove_fixed || (!keep_fixed && valence(keep) < valence(remove))) {
      std::swap(keep, remove);
    }
    const int verdict = check(keep, remove, cand.p);
    if (verdict != 0) {
      (verdict == 1 ? stats_.rejected_topology : stats_.rejected_geometry)++;
      rejected_[keep] = 1;
      rejected_[remove] = 1;
      continue;
    }
    collapse(keep, remove, cand.p);
    faces -= 2;
    ++stats_.collapses;
    stats_.max_error = std::max(stats_.max_error, std::sqrt(cand.cost));
    if (opt_.progress && stats_.collapses % step == 0) opt_.progress(stats_.collapses, total);
  }
  stats_.final_faces = faces;
  if (opt_.progress) opt_.progress(stats_.collapses, std::max(total, stats_.collapses));
  return stats_;
}

}  // namespace

std::size_t polygon_face_count(const Dlfl& mesh) {
  std::size_t n = 0;
  for (std::uint32_t fi = 0; fi < mesh.face_capacity(); ++fi) {
    const FaceId f(fi);
    if (!mesh.alive(f) || mesh.bounding_labels()[fi] != 0) continue;
    const CornerId c = mesh.first_corner(f);
    if (mesh.next(c) == c || mesh.next(mesh.next(c)) == c) continue;
    ++n;
  }
  return n;
}

DecimateStats decimate(Dlfl& mesh, const DecimateOptions& options) {
  Decimator d(mesh, options);
  return d.run();
}

}  // namespace bisturi::lod
