// Randomised: 100,000 random valid operator calls (seeded, reproducible) on one DLFL holding
// solids of mixed topology; validate() after every call, and every insert_edge is followed by its
// delete_edge_pair, which must restore the structure (face cycles, edge pairs, labels and
// rotation counts).
//
// Reproducibility: the only source of randomness is std::mt19937 with kSeed, and indices are
// drawn with a plain modulo of the raw engine output (no std::*_distribution, whose output is
// implementation-defined). A failure prints the step, the operation and the last operations.

#include <gtest/gtest.h>

#include <algorithm>
#include <chrono>
#include <cstdint>
#include <deque>
#include <iostream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "dlfl_raw_state.h"

namespace bisturi {
namespace {

constexpr std::uint32_t kSeed = 20060611;
constexpr std::size_t kCalls = 100000;
constexpr std::size_t kMinCorners = 300;
constexpr std::size_t kMaxCorners = 1500;

// ---------------------------------------------------------------- canonical snapshot

using Cycle = std::vector<std::uint32_t>;
using IdPair = std::pair<std::uint32_t, std::uint32_t>;

/// The smallest corner id of f's cycle: the cycle's name in a Snapshot.
std::uint32_t smallest_corner(const Dlfl& m, FaceId f) {
  const CornerId start = m.first_corner(f);
  std::uint32_t least = start.idx;
  for (CornerId c = m.next(start); c != start; c = m.next(c))
    least = std::min(least, c.idx);
  return least;
}

/// The structure up to face, edge and rotation numbering, in canonical form: what insert_edge
/// followed by delete_edge_pair must give back. Corner and vertex ids are kept as they are
/// (existing corners survive the round trip). Flat arrays, so that taking one is cheap:
/// - faces: each face cycle as a cyclic sequence of corner ids rotated to start at its smallest
///   id, the cycles sorted by that id, each stored as [length, label, ids...]. Cycles are
///   disjoint, so walking the corners in id order and starting a cycle at each corner not yet
///   seen gives exactly this order and rotation.
/// - edges: each edge as its pairs, a pair as (smaller, larger) corner id, pairs sorted, edges
///   sorted by their smallest corner id, each stored as [pair count, a0, b0, a1, b1, ...].
/// - rotations: [vertex id, rotation count] for every live vertex, in id order.
struct Snapshot {
  std::vector<std::uint32_t> faces;
  std::vector<std::uint32_t> edges;
  std::vector<std::uint32_t> rotations;

  bool operator==(const Snapshot&) const = default;
};

Snapshot snapshot(const Dlfl& m) {
  Snapshot s;
  const std::size_t nc = m.corner_capacity();
  std::vector<char> seen(nc, 0);
  std::vector<char> edge_seen(m.edge_capacity(), 0);
  std::vector<IdPair> pairs;
  const auto& extra = m.extra_pair_lists();
  for (std::uint32_t i = 0; i < nc; ++i) {
    const CornerId first(i);
    if (!m.alive(first)) continue;
    if (!seen[i]) {
      const std::size_t header = s.faces.size();
      s.faces.push_back(0);
      s.faces.push_back(m.is_bounding(m.face(first)) ? 1 : 0);
      CornerId c = first;
      do {
        seen[c.idx] = 1;
        s.faces.push_back(c.idx);
        c = m.next(c);
      } while (c != first);
      s.faces[header] = static_cast<std::uint32_t>(s.faces.size() - header - 2);
    }
    const EdgeId e = m.edge(first);
    if (e.valid() && !edge_seen[e.idx]) {
      edge_seen[e.idx] = 1;
      pairs.clear();
      auto add = [&](const CornerPair& p) {
        pairs.emplace_back(std::min(p.a.idx, p.b.idx), std::max(p.a.idx, p.b.idx));
      };
      add(m.primary_pair(e));
      const auto it =
          std::lower_bound(extra.begin(), extra.end(), e.idx,
                           [](const auto& entry, std::uint32_t key) { return entry.first < key; });
      if (it != extra.end() && it->first == e.idx) {
        for (const CornerPair& p : it->second)
          add(p);
      }
      std::sort(pairs.begin(), pairs.end());
      s.edges.push_back(static_cast<std::uint32_t>(pairs.size()));
      for (const auto& [a, b] : pairs)
        s.edges.insert(s.edges.end(), {a, b});
    }
  }
  for (std::uint32_t i = 0; i < m.vertex_capacity(); ++i) {
    const VertexId v(i);
    if (m.alive(v)) {
      s.rotations.insert(s.rotations.end(), {i, static_cast<std::uint32_t>(rotation_count(m, v))});
    }
  }
  return s;
}

/// Sets the label of the snapshot's cycle named by its smallest corner id.
void set_label(Snapshot& s, std::uint32_t smallest, bool label) {
  for (std::size_t pos = 0; pos < s.faces.size(); pos += 2 + s.faces[pos]) {
    if (s.faces[pos + 2] == smallest) s.faces[pos + 1] = label ? 1 : 0;
  }
}

/// Renames every corner and vertex id of the snapshot (maps that keep the id order, so the
/// canonical order is kept too).
void rename(Snapshot& s, const std::vector<std::uint32_t>& corner_map,
            const std::vector<std::uint32_t>& vertex_map) {
  for (std::size_t pos = 0; pos < s.faces.size(); pos += 2 + s.faces[pos]) {
    for (std::size_t k = pos + 2; k < pos + 2 + s.faces[pos]; ++k) {
      s.faces[k] = corner_map[s.faces[k]];
    }
  }
  for (std::size_t pos = 0; pos < s.edges.size(); pos += 1 + 2 * std::size_t{s.edges[pos]}) {
    for (std::size_t k = pos + 1; k < pos + 1 + 2 * std::size_t{s.edges[pos]}; ++k) {
      s.edges[k] = corner_map[s.edges[k]];
    }
  }
  for (std::size_t k = 0; k < s.rotations.size(); k += 2) {
    s.rotations[k] = vertex_map[s.rotations[k]];
  }
}

std::vector<std::pair<Cycle, bool>> face_list(const Snapshot& s) {
  std::vector<std::pair<Cycle, bool>> out;
  for (std::size_t pos = 0; pos < s.faces.size(); pos += 2 + s.faces[pos]) {
    const auto begin = s.faces.begin() + static_cast<std::ptrdiff_t>(pos + 2);
    out.emplace_back(Cycle(begin, begin + s.faces[pos]), s.faces[pos + 1] != 0);
  }
  return out;
}

std::vector<std::vector<IdPair>> edge_list(const Snapshot& s) {
  std::vector<std::vector<IdPair>> out;
  for (std::size_t pos = 0; pos < s.edges.size(); pos += 1 + 2 * std::size_t{s.edges[pos]}) {
    auto& pairs = out.emplace_back();
    for (std::size_t k = 0; k < s.edges[pos]; ++k) {
      pairs.emplace_back(s.edges[pos + 1 + 2 * k], s.edges[pos + 2 + 2 * k]);
    }
  }
  return out;
}

std::string to_text(const Cycle& c) {
  std::string s;
  for (std::uint32_t x : c)
    s += (s.empty() ? "c" : " c") + std::to_string(x);
  return s;
}

/// The first few differences between two snapshots, for failure messages.
std::string difference(const Snapshot& want_snapshot, const Snapshot& got_snapshot) {
  std::ostringstream out;
  const auto want = face_list(want_snapshot);
  const auto got = face_list(got_snapshot);
  std::vector<std::pair<Cycle, bool>> missing, extra;
  std::set_difference(want.begin(), want.end(), got.begin(), got.end(),
                      std::back_inserter(missing));
  std::set_difference(got.begin(), got.end(), want.begin(), want.end(), std::back_inserter(extra));
  for (std::size_t i = 0; i < missing.size() && i < 4; ++i) {
    out << "  expected face (" << to_text(missing[i].first) << ")"
        << (missing[i].second ? " labelled" : "") << " is missing\n";
  }
  for (std::size_t i = 0; i < extra.size() && i < 4; ++i) {
    out << "  unexpected face (" << to_text(extra[i].first) << ")"
        << (extra[i].second ? " labelled" : "") << "\n";
  }
  const auto want_edges = edge_list(want_snapshot);
  const auto got_edges = edge_list(got_snapshot);
  std::vector<std::vector<IdPair>> missing_edges, extra_edges;
  std::set_difference(want_edges.begin(), want_edges.end(), got_edges.begin(), got_edges.end(),
                      std::back_inserter(missing_edges));
  std::set_difference(got_edges.begin(), got_edges.end(), want_edges.begin(), want_edges.end(),
                      std::back_inserter(extra_edges));
  auto edge_text = [](const std::vector<IdPair>& pairs) {
    std::string s;
    for (const auto& [a, b] : pairs) {
      s += " (c" + std::to_string(a) + ",c" + std::to_string(b) + ")";
    }
    return s;
  };
  for (std::size_t i = 0; i < missing_edges.size() && i < 4; ++i) {
    out << "  expected edge" << edge_text(missing_edges[i]) << " is missing\n";
  }
  for (std::size_t i = 0; i < extra_edges.size() && i < 4; ++i) {
    out << "  unexpected edge" << edge_text(extra_edges[i]) << "\n";
  }
  if (want_snapshot.rotations != got_snapshot.rotations) out << "  rotation counts differ\n";
  return out.str();
}

/// Live counts of every element kind.
struct Counts {
  std::size_t vertices = 0, corners = 0, faces = 0, edges = 0, rotations = 0;
  bool operator==(const Counts&) const = default;
};

Counts counts(const Dlfl& m) {
  return {m.num_vertices(), m.num_corners(), m.num_faces(), m.num_edges(), m.num_rotations()};
}

std::ostream& operator<<(std::ostream& out, const Counts& n) {
  return out << "V" << n.vertices << " C" << n.corners << " F" << n.faces << " E" << n.edges << " R"
             << n.rotations;
}

using testing_support::raw_state;
using testing_support::RawState;

// ---------------------------------------------------------------- statistics

using PartKey = std::vector<std::int64_t>;

std::vector<PartKey> part_keys(const MeshStatistics& s) {
  std::vector<PartKey> keys;
  for (const PartTopology& t : s.parts) {
    keys.push_back({static_cast<std::int64_t>(t.vertices), static_cast<std::int64_t>(t.edges),
                    static_cast<std::int64_t>(t.faces), static_cast<std::int64_t>(t.rings),
                    t.euler_characteristic, t.genus});
  }
  std::sort(keys.begin(), keys.end());
  return keys;
}

std::vector<std::size_t> stat_fields(const MeshStatistics& s) {
  return {s.vertices,           s.corners,        s.faces,         s.edges,
          s.rotations,          s.bounding_faces, s.point_spheres, s.non_manifold_vertices,
          s.non_manifold_edges, s.parts.size()};
}

// ---------------------------------------------------------------- the mixed-topology subject

PolygonMesh moved(PolygonMesh p, const Dlfl::Vec3& by) {
  for (auto& x : p.positions)
    x += by;
  return p;
}

/// Tetrahedron, torus (genus 1), open grid (one ring), tube (two rings), two tetrahedra sharing
/// a vertex (two rotations on it) and four lone point spheres, all in one structure.
void build_mixed(Dlfl& m) {
  append_oriented_manifold(m, tetrahedron_mesh());
  append_oriented_manifold(m, moved(torus_mesh(3.0, 1.0, 6, 4, true), {10, 0, 0}));
  append_oriented_manifold(m, moved(grid_mesh(3, 3, 1.0, false), {20, 0, 0}));
  append_oriented_manifold(m, moved(tube_mesh(1.0, 2.0, 6, 2), {30, 0, 0}));
  const auto first = append_oriented_manifold(m, moved(tetrahedron_mesh(), {40, 0, 0}));
  BuildOptions join;
  join.join_vertices.assign(4, VertexId{});
  join.join_vertices[0] = first[0];
  append_oriented_manifold(m, moved(tetrahedron_mesh(), {40, 0, 0}), join);
  for (int i = 0; i < 4; ++i)
    m.create_vertex({50.0 + i, 0, 0});
}

// ---------------------------------------------------------------- the run

class RandomOperators : public ::testing::Test {
 protected:
  enum class Op {
    kCreateVertex,
    kDeleteVertex,
    kInsertAny,
    kInsertSameFace,
    kInsertJoined,
    kDeleteEdgePair,
    kDeleteEdge,
    kAddRotation,
    kCleanRotations,
    kSetBounding,
    kCompact,
    kCount
  };

  void SetUp() override {
    build_mixed(mesh_);
    serial_ = &mesh_.vertex_properties().add<std::uint64_t>("serial", 0);
    for (std::uint32_t i = 0; i < mesh_.vertex_capacity(); ++i) {
      if (mesh_.alive(VertexId(i))) give_serial(VertexId(i));
    }
  }

  // ---- random draws: modulo of the raw engine output, never a std distribution ----
  std::uint32_t below(std::size_t n) { return static_cast<std::uint32_t>(rng_() % n); }
  bool chance(std::uint32_t percent) { return below(100) < percent; }
  Dlfl::Vec3 random_position() {
    return {double(below(2001)) / 100.0 - 10.0, double(below(2001)) / 100.0 - 10.0,
            double(below(2001)) / 100.0 - 10.0};
  }

  template <class Tag>
  Handle<Tag> random_live(std::size_t capacity) {
    for (int attempt = 0; attempt < 256 && capacity > 0; ++attempt) {
      const Handle<Tag> h(below(capacity));
      if (mesh_.alive(h)) return h;
    }
    return {};
  }
  CornerId random_corner() { return random_live<CornerTag>(mesh_.corner_capacity()); }
  VertexId random_vertex() { return random_live<VertexTag>(mesh_.vertex_capacity()); }
  FaceId random_face() { return random_live<FaceTag>(mesh_.face_capacity()); }
  EdgeId random_edge() { return random_live<EdgeTag>(mesh_.edge_capacity()); }

  std::vector<RotationId> rotations_of(VertexId v) const {
    std::vector<RotationId> out;
    for (RotationId r = mesh_.first_rotation(v); r.valid(); r = mesh_.next_rotation(r)) {
      out.push_back(r);
    }
    return out;
  }

  void give_serial(VertexId v) {
    (*serial_)[v] = ++last_serial_;
    position_of_serial_[last_serial_] = mesh_.position(v);
  }

  // ---- bookkeeping and failure context ----
  void note(std::string what) {
    recent_.push_back(std::to_string(calls_) + ": " + std::move(what));
    if (recent_.size() > 12) recent_.pop_front();
  }
  /// Counts one operator call.
  void counted(Op op) {
    ++calls_;
    ++op_count_[static_cast<std::size_t>(op)];
  }
  std::string where(const char* op) const {
    std::string s = "seed " + std::to_string(kSeed) + ", call " + std::to_string(calls_) + " (" +
                    op + "); last calls:\n";
    for (const auto& r : recent_)
      s += "  " + r + "\n";
    return s;
  }
  void expect_valid(const char* op) {
    const ValidationReport report = validate(mesh_);
    ASSERT_TRUE(report.ok()) << where(op) << report.summary();
  }

  static const char* name(Op op) {
    static const char* const kNames[] = {
        "create_vertex",       "delete_vertex",    "insert_edge(any)", "insert_edge(same face)",
        "insert_edge(joined)", "delete_edge_pair", "delete_edge",      "add_rotation",
        "clean_rotations",     "set_bounding",     "compact"};
    return kNames[static_cast<std::size_t>(op)];
  }

  Op choose() {
    if (below(4000) == 0) return Op::kCompact;
    const std::size_t n = mesh_.num_corners();
    // Weights per op (same order as Op). An insert leaves its edge in place half of the time,
    // so inserts and deletes are weighted to let the mesh grow slowly until it has about
    // kMaxCorners corners, then shrink it a little: the size stays bounded and validate() cheap.
    std::vector<std::uint32_t> w;
    if (n > kMaxCorners) {
      w = {1, 8, 6, 6, 2, 36, 14, 1, 10, 12};
    } else if (n < kMinCorners) {
      w = {6, 1, 24, 20, 6, 4, 2, 6, 3, 12};
    } else {
      w = {4, 4, 18, 16, 6, 11, 4, 5, 6, 13};
    }
    std::uint32_t total = 0;
    for (std::uint32_t x : w)
      total += x;
    std::uint32_t r = below(total);
    for (std::size_t i = 0; i < w.size(); ++i) {
      if (r < w[i]) return static_cast<Op>(i);
      r -= w[i];
    }
    return Op::kSetBounding;
  }

  /// One random operation; returns false when it found nothing to do (not counted).
  bool step() {
    const Op op = choose();
    switch (op) {
      case Op::kCreateVertex:
        return do_create_vertex();
      case Op::kDeleteVertex:
        return do_delete_vertex();
      case Op::kInsertAny:
      case Op::kInsertSameFace:
      case Op::kInsertJoined:
        return do_insert(op);
      case Op::kDeleteEdgePair:
      case Op::kDeleteEdge:
        return do_delete(op);
      case Op::kAddRotation:
        return do_add_rotation();
      case Op::kCleanRotations:
        return do_clean_rotations();
      case Op::kSetBounding:
        return do_set_bounding();
      case Op::kCompact:
        return do_compact();
      case Op::kCount:
        break;
    }
    return false;
  }

  bool do_create_vertex() {
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    const Dlfl::Vec3 p = random_position();
    const VertexId v = mesh_.create_vertex(p);
    counted(Op::kCreateVertex);
    note("create_vertex() -> " + to_string(v));
    expect_valid("create_vertex");
    if (HasFatalFailure()) return true;
    // A new (or reused) slot carries the property's default value.
    EXPECT_EQ((*serial_)[v], 0u) << where("create_vertex");
    give_serial(v);
    const Counts want{n0.vertices + 1, n0.corners + 1, n0.faces + 1, n0.edges, n0.rotations + 1};
    EXPECT_EQ(counts(mesh_), want) << where("create_vertex");
    EXPECT_GT(mesh_.topology_version(), version) << where("create_vertex");
    EXPECT_EQ(mesh_.position(v), p);
    EXPECT_EQ(rotation_count(mesh_, v), 1u);
    EXPECT_TRUE(mesh_.is_point_sphere(mesh_.rotation_corner(mesh_.first_rotation(v))));
    return true;
  }

  bool do_delete_vertex() {
    std::vector<VertexId> lone;
    for (std::uint32_t i = 0; i < mesh_.vertex_capacity(); ++i) {
      const VertexId v(i);
      if (!mesh_.alive(v)) continue;
      const RotationId r = mesh_.first_rotation(v);
      if (!mesh_.next_rotation(r).valid() && mesh_.is_point_sphere(mesh_.rotation_corner(r))) {
        lone.push_back(v);
      }
    }
    if (lone.empty()) return false;
    const VertexId v = lone[below(lone.size())];
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    mesh_.delete_vertex(v);
    counted(Op::kDeleteVertex);
    note("delete_vertex(" + to_string(v) + ")");
    expect_valid("delete_vertex");
    if (HasFatalFailure()) return true;
    const Counts want{n0.vertices - 1, n0.corners - 1, n0.faces - 1, n0.edges, n0.rotations - 1};
    EXPECT_EQ(counts(mesh_), want) << where("delete_vertex");
    EXPECT_FALSE(mesh_.alive(v));
    EXPECT_GT(mesh_.topology_version(), version) << where("delete_vertex");
    return true;
  }

  /// Whether an edge joining the vertices of c1 and c2 already has a pair in their rotations.
  bool pair_in_rotations(CornerId c1, CornerId c2) const {
    const VertexId v1 = mesh_.vertex(c1);
    const VertexId v2 = mesh_.vertex(c2);
    const RotationId r1 = mesh_.rotation_of(c1);
    const RotationId r2 = mesh_.rotation_of(c2);
    for (RotationId r : rotations_of(v1)) {
      for (CornerId c : rotation_corners(mesh_, r)) {
        if (mesh_.is_point_sphere(c) || mesh_.vertex(mesh_.next(c)) != v2) continue;
        for (const CornerPair& p : mesh_.edge_pairs(mesh_.edge(c))) {
          const CornerId at1 = mesh_.vertex(p.a) == v1 ? p.a : p.b;
          const CornerId at2 = at1 == p.a ? p.b : p.a;
          if (mesh_.rotation_of(at1) == r1 && mesh_.rotation_of(at2) == r2) return true;
        }
      }
    }
    return false;
  }

  /// Picks the corners for an insert of the given kind; false if none found.
  bool pick_insert_corners(Op op, CornerId& c1, CornerId& c2) {
    for (int attempt = 0; attempt < 16; ++attempt) {
      if (op == Op::kInsertAny) {
        c1 = random_corner();
        c2 = random_corner();
      } else if (op == Op::kInsertSameFace) {
        // The face of a random corner: larger faces are picked more often.
        const CornerId c = random_corner();
        if (!c.valid()) return false;
        const std::vector<CornerId> cs = face_corners(mesh_, mesh_.face(c));
        if (cs.size() < 2) continue;
        c1 = cs[below(cs.size())];
        c2 = cs[below(cs.size())];
      } else {
        // A second pair for an edge that lives in another rotation of v1.
        const std::vector<VertexId> junctions = non_manifold_vertices(mesh_);
        if (junctions.empty()) return false;
        const VertexId v1 = junctions[below(junctions.size())];
        const std::vector<RotationId> rs = rotations_of(v1);
        std::vector<std::pair<std::size_t, CornerId>> sides;  // (rotation index, side)
        for (std::size_t i = 0; i < rs.size(); ++i) {
          for (CornerId c : rotation_corners(mesh_, rs[i])) {
            if (!mesh_.is_point_sphere(c)) sides.emplace_back(i, c);
          }
        }
        if (sides.empty()) continue;
        const auto [rot, side] = sides[below(sides.size())];
        const VertexId v2 = mesh_.vertex(mesh_.next(side));
        std::size_t other = below(rs.size() - 1);
        if (other >= rot) ++other;
        const std::vector<CornerId> at1 = rotation_corners(mesh_, rs[other]);
        std::vector<CornerId> at2;
        for (RotationId r : rotations_of(v2)) {
          for (CornerId c : rotation_corners(mesh_, r))
            at2.push_back(c);
        }
        c1 = at1[below(at1.size())];
        c2 = at2[below(at2.size())];
      }
      if (c1.valid() && c2.valid() && mesh_.vertex(c1) != mesh_.vertex(c2)) return true;
    }
    return false;
  }

  /// insert_edge with every check of its result; nullopt when it was refused (labelled faces in
  /// opposite orientations), which must leave the structure bit-identical.
  std::optional<InsertEdgeResult> checked_insert(CornerId c1, CornerId c2,
                                                 const InsertEdgeOptions& options, Op op,
                                                 const char* label) {
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    const FaceId f1 = mesh_.face(c1);
    const FaceId f2 = mesh_.face(c2);
    const bool split = f1 == f2;
    const bool l1 = mesh_.is_bounding(f1);
    const bool l2 = mesh_.is_bounding(f2);
    const bool ps1 = mesh_.is_point_sphere(c1);
    const bool ps2 = mesh_.is_point_sphere(c2);
    const VertexId v1 = mesh_.vertex(c1);
    const VertexId v2 = mesh_.vertex(c2);
    const bool may_refuse = !split && l1 && l2 && options.check_label_orientation;
    std::optional<RawState> raw;
    if (may_refuse) raw = raw_state(mesh_);
    const std::string call = "insert_edge(" + to_string(c1) + ", " + to_string(c2) + ", " +
                             (options.label_side == LabelSide::Forward ? "Forward" : "Backward") +
                             (options.check_label_orientation ? "" : ", no orientation check") +
                             ")";
    InsertEdgeResult r;
    try {
      r = mesh_.insert_edge(c1, c2, options);
    } catch (const LabelOrientationError&) {
      EXPECT_TRUE(may_refuse) << where(label) << call << " refused";
      EXPECT_TRUE(raw && raw_state(mesh_) == *raw) << where(label) << call << " changed data";
      ++label_refusals_;
      return std::nullopt;
    }
    counted(op);
    note(call + " -> side12 " + to_string(r.side12) + (r.split ? " split" : " merge") +
         (r.joined_existing ? " joined" : ""));
    expect_valid(label);
    if (HasFatalFailure()) return std::nullopt;

    const std::string w = where(label);
    EXPECT_EQ(r.split, split) << w;
    const std::size_t spheres = (ps1 ? 1 : 0) + (ps2 ? 1 : 0);
    const Counts want{n0.vertices, n0.corners + 2 - spheres, split ? n0.faces + 1 : n0.faces - 1,
                      r.joined_existing ? n0.edges : n0.edges + 1, n0.rotations};
    EXPECT_EQ(counts(mesh_), want) << w;
    EXPECT_GT(mesh_.topology_version(), version) << w;
    EXPECT_EQ(mesh_.vertex(r.side12), v1) << w;
    EXPECT_EQ(mesh_.vertex(r.side21), v2) << w;
    EXPECT_EQ(mesh_.next(r.side12), c2) << w;
    EXPECT_EQ(mesh_.next(r.side21), c1) << w;
    EXPECT_EQ(mesh_.edge(r.side12), r.edge) << w;
    EXPECT_EQ(mesh_.edge(r.side21), r.edge) << w;
    EXPECT_EQ(mesh_.partner(r.side12), r.side21) << w;
    EXPECT_EQ(r.side12 == c1, ps1) << w;
    EXPECT_EQ(r.side21 == c2, ps2) << w;
    EXPECT_EQ(mesh_.edge_pair_count(r.edge) > 1, r.joined_existing) << w;
    EXPECT_EQ(mesh_.face(r.side12), r.face_forward) << w;
    EXPECT_EQ(mesh_.face(r.side21), r.face_backward) << w;
    if (split) {
      EXPECT_NE(r.face_forward, r.face_backward) << w;
      EXPECT_EQ(mesh_.face(c2), r.face_forward) << w;
      EXPECT_EQ(mesh_.face(c1), r.face_backward) << w;
      const bool forward = options.label_side == LabelSide::Forward;
      EXPECT_EQ(mesh_.is_bounding(r.face_forward), l1 && forward) << w;
      EXPECT_EQ(mesh_.is_bounding(r.face_backward), l1 && !forward) << w;
      ++splits_;
      ++(l1 ? labelled_splits_ : unlabelled_splits_);
    } else {
      EXPECT_EQ(r.face_forward, r.face_backward) << w;
      EXPECT_EQ(mesh_.face(c1), r.face_forward) << w;
      EXPECT_EQ(mesh_.face(c2), r.face_forward) << w;
      EXPECT_EQ(mesh_.is_bounding(r.face_forward), l1 || l2) << w;
      ++merges_;
      ++(spheres > 0 ? point_sphere_merges_ : face_face_merges_);
      if (!l1 && !l2) ++unlabelled_merges_;
      if (l1 && l2) ++labelled_pair_merges_;
    }
    if (r.joined_existing) ++joined_existing_;
    return r;
  }

  bool do_insert(Op op) {
    if (calls_ + 2 > kCalls) return false;  // the insert and its delete both count
    CornerId c1, c2;
    if (!pick_insert_corners(op, c1, c2)) return false;
    InsertEdgeOptions options;
    options.label_side = chance(50) ? LabelSide::Forward : LabelSide::Backward;
    options.check_label_orientation = chance(75);

    const Snapshot before = snapshot(mesh_);
    const Counts n0 = counts(mesh_);
    const FaceId f1 = mesh_.face(c1);
    const FaceId f2 = mesh_.face(c2);
    const bool l1 = mesh_.is_bounding(f1);
    const bool l2 = mesh_.is_bounding(f2);
    const std::uint32_t k1 = smallest_corner(mesh_, f1);
    const std::uint32_t k2 = smallest_corner(mesh_, f2);
    // In joined mode an edge to v2 lives in another rotation of v1, so the new pair must join
    // one (unless the two rotations already hold a v1-v2 pair: then a parallel edge is fine).
    const bool must_join = op == Op::kInsertJoined && !pair_in_rotations(c1, c2);

    const auto r = checked_insert(c1, c2, options, op, name(op));
    if (HasFatalFailure()) return true;
    if (!r) return false;  // refused: not a call
    if (op == Op::kInsertJoined) {
      EXPECT_TRUE(!must_join || r->joined_existing) << where(name(op));
      ++joined_mode_inserts_;
    }

    // Its delete must give the structure back.
    const auto version = mesh_.topology_version();
    const DeleteEdgeResult d = mesh_.delete_edge_pair(r->side12);
    counted(Op::kDeleteEdgePair);
    note("delete_edge_pair(" + to_string(r->side12) + ") [undo]");
    expect_valid("delete_edge_pair (undo of insert_edge)");
    if (HasFatalFailure()) return true;
    const std::string w = where("delete_edge_pair (undo of insert_edge)");
    EXPECT_EQ(d.split, !r->split) << w;
    EXPECT_GT(mesh_.topology_version(), version) << w;
    EXPECT_EQ(counts(mesh_), n0) << w;
    EXPECT_TRUE(mesh_.alive(c1) && mesh_.alive(c2)) << w;
    // The corners the insert created are gone again.
    EXPECT_TRUE(r->side12 == c1 || !mesh_.alive(r->side12)) << w;
    EXPECT_TRUE(r->side21 == c2 || !mesh_.alive(r->side21)) << w;
    Snapshot want = before;
    if (!r->split && l1 != l2) {
      // Documented exception: the delete-split of the labelled merged face labels both pieces.
      set_label(want, k1, true);
      set_label(want, k2, true);
      ++label_exceptions_;
    }
    const Snapshot after = snapshot(mesh_);
    EXPECT_TRUE(after == want) << w << difference(want, after);
    if (HasFailure()) return true;
    ++undo_checks_;

    // Keep the mesh evolving: re-insert the same edge half of the time.
    if (calls_ < kCalls && chance(50)) {
      const auto again = checked_insert(c1, c2, options, op, "insert_edge (re-insert)");
      if (HasFatalFailure()) return true;
      if (again) {
        EXPECT_EQ(again->split, r->split) << where("insert_edge (re-insert)");
        EXPECT_EQ(again->joined_existing, r->joined_existing) << where("insert_edge (re-insert)");
        ++reinserts_;
      }
    }
    return true;
  }

  bool do_delete(Op op) {
    const EdgeId e = random_edge();
    if (!e.valid()) return false;
    const std::vector<CornerPair> pairs = mesh_.edge_pairs(e);
    const CornerPair p = pairs[below(pairs.size())];
    const bool whole = op == Op::kDeleteEdge;
    const CornerId side = chance(50) ? p.a : p.b;
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    const bool dangling_a = mesh_.prev(p.a) == p.b;
    const bool dangling_b = mesh_.prev(p.b) == p.a;
    const FaceId fa = mesh_.face(p.a);
    const FaceId fb = mesh_.face(p.b);
    const bool same = fa == fb;
    const bool la = mesh_.is_bounding(fa);
    const bool lb = mesh_.is_bounding(fb);

    const DeleteEdgeResult d = whole ? mesh_.delete_edge(e) : mesh_.delete_edge_pair(side);
    counted(op);
    note(whole ? "delete_edge(" + to_string(e) + ") of " + std::to_string(pairs.size()) + " pairs"
               : "delete_edge_pair(" + to_string(side) + ")");
    expect_valid(name(op));
    if (HasFatalFailure()) return true;
    const std::string w = where(name(op));
    EXPECT_GT(mesh_.topology_version(), version) << w;
    if (whole) {
      EXPECT_FALSE(mesh_.alive(e)) << w;
      EXPECT_EQ(mesh_.num_edges(), n0.edges - 1) << w;
      EXPECT_EQ(mesh_.num_vertices(), n0.vertices) << w;
      EXPECT_EQ(mesh_.num_rotations(), n0.rotations) << w;
      if (pairs.size() > 1) {
        ++multi_pair_edge_deletes_;
        return true;
      }
    } else {
      EXPECT_EQ(mesh_.alive(e), pairs.size() > 1) << w;
      if (pairs.size() > 1) ++joined_pair_deletes_;
    }
    // One pair went: the exact figures are known.
    const std::size_t kept_corners = (dangling_a ? 1 : 0) + (dangling_b ? 1 : 0);
    const Counts want{n0.vertices, n0.corners - 2 + kept_corners,
                      same ? n0.faces + 1 : n0.faces - 1,
                      pairs.size() > 1 ? n0.edges : n0.edges - 1, n0.rotations};
    EXPECT_EQ(counts(mesh_), want) << w;
    EXPECT_EQ(d.split, same) << w;
    EXPECT_EQ(mesh_.alive(p.a) && mesh_.is_point_sphere(p.a), dangling_a) << w;
    EXPECT_EQ(mesh_.alive(p.b) && mesh_.is_point_sphere(p.b), dangling_b) << w;
    EXPECT_TRUE(dangling_a || !mesh_.alive(p.a)) << w;
    EXPECT_TRUE(dangling_b || !mesh_.alive(p.b)) << w;
    if (same) {
      EXPECT_NE(d.face_a, d.face_b) << w;
      EXPECT_EQ(mesh_.is_bounding(d.face_a), la) << w;
      EXPECT_EQ(mesh_.is_bounding(d.face_b), la) << w;
      ++delete_splits_;
      if (la) ++labelled_delete_splits_;
      if (kept_corners > 0) ++spike_deletes_;
    } else {
      EXPECT_EQ(d.face_a, d.face_b) << w;
      EXPECT_EQ(mesh_.is_bounding(d.face_a), la || lb) << w;
      ++delete_merges_;
      if (la != lb) ++mixed_label_delete_merges_;
    }
    return true;
  }

  bool do_add_rotation() {
    const VertexId v = random_vertex();
    if (!v.valid()) return false;
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    const RotationId first = mesh_.first_rotation(v);
    const std::size_t rotations = rotation_count(mesh_, v);
    const AddRotationResult r = mesh_.add_rotation(v);
    counted(Op::kAddRotation);
    note("add_rotation(" + to_string(v) + ") -> " + to_string(r.corner));
    expect_valid("add_rotation");
    if (HasFatalFailure()) return true;
    const std::string w = where("add_rotation");
    const Counts want{n0.vertices, n0.corners + 1, n0.faces + 1, n0.edges, n0.rotations + 1};
    EXPECT_EQ(counts(mesh_), want) << w;
    EXPECT_GT(mesh_.topology_version(), version) << w;
    EXPECT_EQ(rotation_count(mesh_, v), rotations + 1) << w;
    EXPECT_EQ(mesh_.first_rotation(v), first) << w;
    EXPECT_EQ(rotations_of(v).back(), r.rotation) << w;
    EXPECT_EQ(mesh_.rotation_corner(r.rotation), r.corner) << w;
    EXPECT_EQ(mesh_.vertex(r.corner), v) << w;
    EXPECT_EQ(mesh_.face(r.corner), r.face) << w;
    EXPECT_TRUE(mesh_.is_point_sphere(r.corner)) << w;
    EXPECT_FALSE(mesh_.is_bounding(r.face)) << w;
    return true;
  }

  bool do_clean_rotations() {
    VertexId v;
    if (chance(70)) {
      const std::vector<VertexId> junctions = non_manifold_vertices(mesh_);
      if (!junctions.empty()) v = junctions[below(junctions.size())];
    }
    if (!v.valid()) v = random_vertex();
    if (!v.valid()) return false;
    const Counts n0 = counts(mesh_);
    const auto version = mesh_.topology_version();
    const std::vector<RotationId> rs = rotations_of(v);
    std::vector<RotationId> kept;
    for (RotationId r : rs) {
      if (!mesh_.is_point_sphere(mesh_.rotation_corner(r))) kept.push_back(r);
    }
    if (kept.empty()) kept.push_back(rs.front());
    const std::size_t removed = rs.size() - kept.size();
    mesh_.clean_rotations(v);
    counted(Op::kCleanRotations);
    note("clean_rotations(" + to_string(v) + ") removing " + std::to_string(removed));
    expect_valid("clean_rotations");
    if (HasFatalFailure()) return true;
    const std::string w = where("clean_rotations");
    EXPECT_EQ(rotations_of(v), kept) << w;
    const Counts want{n0.vertices, n0.corners - removed, n0.faces - removed, n0.edges,
                      n0.rotations - removed};
    EXPECT_EQ(counts(mesh_), want) << w;
    if (removed > 0) {
      EXPECT_GT(mesh_.topology_version(), version) << w;
      rotations_removed_ += removed;
    } else {
      EXPECT_GE(mesh_.topology_version(), version) << w;
    }
    return true;
  }

  bool do_set_bounding() {
    // Label about a third of the time, so that labels neither vanish nor take over.
    const bool label = chance(35);
    FaceId f;
    for (int attempt = 0; attempt < 8 && !f.valid(); ++attempt) {
      const FaceId g = random_face();
      if (g.valid() && mesh_.is_bounding(g) != label) f = g;
    }
    if (!f.valid()) return false;
    const Counts n0 = counts(mesh_);
    mesh_.set_bounding(f, label);
    counted(Op::kSetBounding);
    note("set_bounding(" + to_string(f) + ", " + (label ? "true" : "false") + ")");
    expect_valid("set_bounding");
    if (HasFatalFailure()) return true;
    EXPECT_EQ(mesh_.is_bounding(f), label) << where("set_bounding");
    EXPECT_EQ(counts(mesh_), n0) << where("set_bounding");
    return true;
  }

  bool do_compact() {
    const Snapshot before = snapshot(mesh_);
    const MeshStatistics stats = mesh_statistics(mesh_);
    const auto version = mesh_.topology_version();
    // The dense numbering keeps the old order: map the old snapshot's ids through it.
    auto dense = [](std::size_t capacity, auto alive) {
      std::vector<std::uint32_t> map(capacity, kInvalidIndex);
      std::uint32_t next = 0;
      for (std::uint32_t i = 0; i < capacity; ++i) {
        if (alive(i)) map[i] = next++;
      }
      return map;
    };
    const auto cmap =
        dense(mesh_.corner_capacity(), [&](std::uint32_t i) { return mesh_.alive(CornerId(i)); });
    const auto vmap =
        dense(mesh_.vertex_capacity(), [&](std::uint32_t i) { return mesh_.alive(VertexId(i)); });
    Snapshot want = before;
    rename(want, cmap, vmap);

    mesh_.compact();
    counted(Op::kCompact);
    note("compact()");
    expect_valid("compact");
    if (HasFatalFailure()) return true;
    const std::string w = where("compact");
    EXPECT_GT(mesh_.topology_version(), version) << w;
    EXPECT_EQ(mesh_.vertex_capacity(), mesh_.num_vertices()) << w;
    EXPECT_EQ(mesh_.corner_capacity(), mesh_.num_corners()) << w;
    EXPECT_EQ(mesh_.face_capacity(), mesh_.num_faces()) << w;
    EXPECT_EQ(mesh_.edge_capacity(), mesh_.num_edges()) << w;
    EXPECT_EQ(mesh_.rotation_capacity(), mesh_.num_rotations()) << w;
    const MeshStatistics after_stats = mesh_statistics(mesh_);
    EXPECT_EQ(stat_fields(after_stats), stat_fields(stats)) << w;
    EXPECT_EQ(part_keys(after_stats), part_keys(stats)) << w;
    const Snapshot after = snapshot(mesh_);
    EXPECT_TRUE(after == want) << w << difference(want, after);
    // The serial property still sits with its vertex's position.
    for (std::uint32_t i = 0; i < mesh_.vertex_capacity(); ++i) {
      const VertexId v(i);
      const auto it = position_of_serial_.find((*serial_)[v]);
      EXPECT_NE(it, position_of_serial_.end()) << w << to_string(v);
      if (it != position_of_serial_.end()) {
        EXPECT_EQ(mesh_.position(v), it->second) << w;
      }
    }
    return true;
  }

  void report() {
    std::ostringstream out;
    std::size_t labelled = 0;
    for (std::uint32_t i = 0; i < mesh_.face_capacity(); ++i) {
      if (mesh_.alive(FaceId(i)) && mesh_.is_bounding(FaceId(i))) ++labelled;
    }
    out << "dlfl random run, seed " << kSeed << ": " << calls_ << " operator calls, final mesh "
        << counts(mesh_) << ", " << labelled << " labelled faces\n";
    for (std::size_t i = 0; i < static_cast<std::size_t>(Op::kCount); ++i) {
      out << "  " << name(static_cast<Op>(i)) << ": " << op_count_[i] << "\n";
    }
    const std::vector<std::pair<const char*, std::size_t>> figures = {
        {"insert splits", splits_},
        {"insert merges", merges_},
        {"insert merges with a point sphere", point_sphere_merges_},
        {"insert merges of two faces with sides", face_face_merges_},
        {"insert merges of two unlabelled faces", unlabelled_merges_},
        {"insert merges of two labelled faces", labelled_pair_merges_},
        {"insert splits of a labelled face", labelled_splits_},
        {"insert splits of an unlabelled face", unlabelled_splits_},
        {"joined_existing inserts", joined_existing_},
        {"inserts in joined mode", joined_mode_inserts_},
        {"insert/delete round trips checked", undo_checks_},
        {"round trips with the label exception", label_exceptions_},
        {"re-inserts", reinserts_},
        {"refused by label orientation (not counted)", label_refusals_},
        {"delete splits", delete_splits_},
        {"delete splits of a labelled face", labelled_delete_splits_},
        {"delete spikes (point sphere back)", spike_deletes_},
        {"delete merges", delete_merges_},
        {"delete merges labelled+unlabelled", mixed_label_delete_merges_},
        {"pair deletes on non-manifold edges", joined_pair_deletes_},
        {"delete_edge of multi-pair edges", multi_pair_edge_deletes_},
        {"rotations removed by clean_rotations", rotations_removed_},
        {"largest corner count", max_corners_}};
    for (const auto& [what, n] : figures) {
      out << "  " << what << ": " << n << "\n";
      RecordProperty(what, std::to_string(n));
    }
    std::cout << out.str();
  }

  Dlfl mesh_;
  std::mt19937 rng_{kSeed};
  PropertyArray<VertexTag, std::uint64_t>* serial_ = nullptr;
  std::uint64_t last_serial_ = 0;
  std::map<std::uint64_t, Dlfl::Vec3> position_of_serial_;
  std::deque<std::string> recent_;

  std::size_t calls_ = 0;
  std::size_t op_count_[static_cast<std::size_t>(Op::kCount)] = {};
  std::size_t splits_ = 0, merges_ = 0, point_sphere_merges_ = 0, labelled_pair_merges_ = 0;
  std::size_t labelled_splits_ = 0, joined_existing_ = 0, joined_mode_inserts_ = 0;
  std::size_t undo_checks_ = 0, label_exceptions_ = 0, reinserts_ = 0, label_refusals_ = 0;
  std::size_t delete_splits_ = 0, labelled_delete_splits_ = 0, spike_deletes_ = 0;
  std::size_t delete_merges_ = 0, mixed_label_delete_merges_ = 0, joined_pair_deletes_ = 0;
  std::size_t multi_pair_edge_deletes_ = 0, rotations_removed_ = 0, max_corners_ = 0;
  std::size_t unlabelled_splits_ = 0, face_face_merges_ = 0, unlabelled_merges_ = 0;
};

TEST_F(RandomOperators, MixedTopologySubjectIsWhatItClaims) {
  const ValidationReport report = validate(mesh_);
  ASSERT_TRUE(report.ok()) << report.summary();
  const MeshStatistics s = mesh_statistics(mesh_);
  // 4 + 24 + 16 + 18 + 4 + 3 (vertex 0 joined) + 4 point spheres.
  EXPECT_EQ(s.vertices, 73u);
  EXPECT_EQ(s.rotations, 74u);
  EXPECT_EQ(s.non_manifold_vertices, 1u);
  EXPECT_EQ(s.bounding_faces, 3u);
  EXPECT_EQ(s.point_spheres, 4u);
  std::map<std::pair<std::int64_t, std::size_t>, int> kinds;  // (genus, rings) -> parts
  for (const PartTopology& t : s.parts)
    ++kinds[{t.genus, t.rings}];
  // Tetrahedra (3) and point spheres (4) are spheres; torus; grid (1 ring); tube (2 rings).
  const std::map<std::pair<std::int64_t, std::size_t>, int> want = {
      {{0, 0}, 7}, {{1, 0}, 1}, {{0, 1}, 1}, {{0, 2}, 1}};
  EXPECT_EQ(kinds, want);
}

TEST_F(RandomOperators, HundredThousandCallsValidateAndInsertDeleteRoundTrips) {
  const auto start = std::chrono::steady_clock::now();
  {
    const ValidationReport report = validate(mesh_);
    ASSERT_TRUE(report.ok()) << report.summary();
  }
  std::size_t idle = 0;
  while (calls_ < kCalls) {
    const std::size_t before = calls_;
    const bool did = step();
    if (HasFailure()) break;
    max_corners_ = std::max(max_corners_, mesh_.num_corners());
    if (!did || calls_ == before) {
      ASSERT_LT(++idle, 100000u) << "the run found nothing to do";
    }
  }
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  report();
  std::cout << "  time: " << seconds << " s\n";
  ASSERT_FALSE(HasFailure());
  EXPECT_EQ(calls_, kCalls);

  // Every category must have happened, so the run cannot silently degrade.
  for (std::size_t i = 0; i < static_cast<std::size_t>(Op::kCount); ++i) {
    const std::size_t least = static_cast<Op>(i) == Op::kCompact ? 5 : 500;
    EXPECT_GE(op_count_[i], least) << name(static_cast<Op>(i));
  }
  EXPECT_GE(splits_, 1000u);
  EXPECT_GE(merges_, 1000u);
  EXPECT_GE(point_sphere_merges_, 100u);
  EXPECT_GE(face_face_merges_, 100u);
  EXPECT_GE(unlabelled_merges_, 100u);
  EXPECT_GE(unlabelled_splits_, 100u);
  EXPECT_GE(labelled_splits_, 100u);
  EXPECT_GE(labelled_pair_merges_, 10u);
  EXPECT_GE(joined_existing_, 100u);
  EXPECT_GE(undo_checks_, 10000u);
  EXPECT_GE(label_exceptions_, 100u);
  EXPECT_GE(reinserts_, 5000u);
  EXPECT_GE(label_refusals_, 1u);
  EXPECT_GE(delete_splits_, 100u);
  EXPECT_GE(labelled_delete_splits_, 10u);
  EXPECT_GE(spike_deletes_, 100u);
  EXPECT_GE(delete_merges_, 100u);
  EXPECT_GE(mixed_label_delete_merges_, 10u);
  EXPECT_GE(joined_pair_deletes_, 10u);
  EXPECT_GE(multi_pair_edge_deletes_, 1u);
  EXPECT_GE(rotations_removed_, 100u);
}

}  // namespace
}  // namespace bisturi
