// Focused tests of the DLFL operators: refused calls (stale, foreign and invalid handles,
// self-loops, vertices that still have edges) leave the structure bit-identical; splits and
// merges; the label rules of procedures 1 and 2; labelled faces of opposite orientation;
// rotations; compact() with attribute arrays; and the read-only queries on solids of known
// topology.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <functional>
#include <map>
#include <random>
#include <set>
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

// ---------------------------------------------------------------- comparisons

using Cycle = std::vector<std::uint32_t>;
using IdPair = std::pair<std::uint32_t, std::uint32_t>;

Cycle canonical(std::vector<std::uint32_t> ids) {
  std::rotate(ids.begin(), std::min_element(ids.begin(), ids.end()), ids.end());
  return ids;
}

/// The structure up to face and edge numbering: face cycles as cyclic sequences of corner ids
/// (rotated to start at the smallest id) with their labels, the edges as sets of unordered corner
/// pairs, and the rotation count of every live vertex.
struct Snapshot {
  std::set<std::pair<Cycle, bool>> faces;
  std::set<std::vector<IdPair>> edges;
  std::map<std::uint32_t, std::size_t> rotations;
  bool operator==(const Snapshot&) const = default;
};

Snapshot snapshot(const Dlfl& m) {
  Snapshot s;
  for (std::uint32_t i = 0; i < m.face_capacity(); ++i) {
    const FaceId f(i);
    if (!m.alive(f)) continue;
    Cycle ids;
    for (CornerId c : face_corners(m, f))
      ids.push_back(c.idx);
    s.faces.emplace(canonical(std::move(ids)), m.is_bounding(f));
  }
  for (std::uint32_t i = 0; i < m.edge_capacity(); ++i) {
    const EdgeId e(i);
    if (!m.alive(e)) continue;
    std::vector<IdPair> pairs;
    for (const CornerPair& p : m.edge_pairs(e)) {
      pairs.emplace_back(std::min(p.a.idx, p.b.idx), std::max(p.a.idx, p.b.idx));
    }
    std::sort(pairs.begin(), pairs.end());
    s.edges.insert(std::move(pairs));
  }
  for (std::uint32_t i = 0; i < m.vertex_capacity(); ++i) {
    if (m.alive(VertexId(i))) s.rotations[i] = rotation_count(m, VertexId(i));
  }
  return s;
}

using testing_support::raw_state;
using testing_support::RawState;

std::vector<std::size_t> counts(const Dlfl& m) {
  return {m.num_vertices(), m.num_corners(), m.num_faces(), m.num_edges(), m.num_rotations()};
}

void expect_valid(const Dlfl& m, const std::string& when) {
  const ValidationReport report = validate(m);
  EXPECT_TRUE(report.ok()) << when << ":\n" << report.summary();
}

/// `call` must throw a TopologyError (of type E) whose message contains `needle`, and leave the
/// structure exactly as it was.
template <class E = TopologyError>
void expect_refused(Dlfl& m, const std::string& what, const std::string& needle,
                    const std::function<void()>& call) {
  SCOPED_TRACE(what);
  const RawState raw = raw_state(m);
  const Snapshot before = snapshot(m);
  try {
    call();
    ADD_FAILURE() << what << " did not throw";
  } catch (const E& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos)
        << "the message '" << e.what() << "' does not name " << needle;
  } catch (const std::exception& e) {
    ADD_FAILURE() << what << " threw another exception: " << e.what();
  }
  EXPECT_TRUE(raw_state(m) == raw) << what << " changed the raw records";
  EXPECT_TRUE(snapshot(m) == before) << what << " changed the structure";
  EXPECT_EQ(m.topology_version(), raw.version);
  expect_valid(m, what);
}

// ---------------------------------------------------------------- subjects

PolygonMesh moved(PolygonMesh p, const Dlfl::Vec3& by) {
  for (auto& x : p.positions)
    x += by;
  return p;
}

/// One unit square in the z = 0 plane, counter-clockwise seen from +z: as a DLFL, a quad face
/// (normal +z) and its labelled hole face (normal -z) sharing four edges.
PolygonMesh square(const Dlfl::Vec3& at) {
  PolygonMesh p;
  p.positions = {at, at + Dlfl::Vec3(1, 0, 0), at + Dlfl::Vec3(1, 1, 0), at + Dlfl::Vec3(0, 1, 0)};
  p.add_face({0, 1, 2, 3});
  return p;
}

struct Square {
  std::vector<VertexId> vertices;
  FaceId quad;  ///< unlabelled, normal +z
  FaceId hole;  ///< labelled, normal -z
};

Square add_square(Dlfl& m, const Dlfl::Vec3& at) {
  Square s;
  s.vertices = append_oriented_manifold(m, square(at));
  const CornerId c = m.rotation_corner(m.first_rotation(s.vertices[0]));
  for (FaceId f : {m.face(c), m.face(m.rot_next(c))})
    (m.is_bounding(f) ? s.hole : s.quad) = f;
  return s;
}

CornerId corner_of(const Dlfl& m, FaceId f, std::size_t k) {
  return face_corners(m, f)[k];
}

FaceId first_live_face(const Dlfl& m) {
  for (std::uint32_t i = 0; i < m.face_capacity(); ++i) {
    if (m.alive(FaceId(i))) return FaceId(i);
  }
  return {};
}

CornerId only_corner(const Dlfl& m, VertexId v) {
  return m.rotation_corner(m.first_rotation(v));
}

std::vector<RotationId> rotations_of(const Dlfl& m, VertexId v) {
  std::vector<RotationId> out;
  for (RotationId r = m.first_rotation(v); r.valid(); r = m.next_rotation(r))
    out.push_back(r);
  return out;
}

/// (V, E, F, R, chi, genus) of every part, sorted.
std::vector<std::vector<std::int64_t>> part_keys(const Dlfl& m) {
  std::vector<std::vector<std::int64_t>> keys;
  for (const Part& p : connected_parts(m)) {
    const PartTopology t = part_topology(m, p);
    keys.push_back({static_cast<std::int64_t>(t.vertices), static_cast<std::int64_t>(t.edges),
                    static_cast<std::int64_t>(t.faces), static_cast<std::int64_t>(t.rings),
                    t.euler_characteristic, t.genus});
  }
  std::sort(keys.begin(), keys.end());
  return keys;
}

// ---------------------------------------------------------------- refused calls

TEST(DlflOperators, StaleForeignAndInvalidHandlesAreRefusedWithoutChange) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const Square sq = add_square(m, {3, 0, 0});
  // Deleted elements: a vertex with its corner and face, and an edge with its two corners.
  const VertexId dead_vertex = m.create_vertex({9, 9, 9});
  const CornerId dead_sphere = only_corner(m, dead_vertex);
  const FaceId dead_face = m.face(dead_sphere);
  m.delete_vertex(dead_vertex);
  const CornerId side = m.rotation_corner(m.first_rotation(cube[0]));
  const EdgeId dead_edge = m.edge(side);
  const CornerPair dead_pair = m.primary_pair(dead_edge);
  m.delete_edge(dead_edge);
  ASSERT_FALSE(m.alive(dead_vertex));
  ASSERT_FALSE(m.alive(dead_sphere));
  ASSERT_FALSE(m.alive(dead_face));
  ASSERT_FALSE(m.alive(dead_edge));
  ASSERT_FALSE(m.alive(dead_pair.a));
  ASSERT_FALSE(m.alive(dead_pair.b));
  expect_valid(m, "after the deletions");

  const CornerId good = m.first_corner(sq.quad);
  const std::vector<CornerId> bad_corners = {
      dead_sphere, dead_pair.a, CornerId(static_cast<std::uint32_t>(m.corner_capacity() + 7)),
      CornerId{}};
  const std::vector<EdgeId> bad_edges = {
      dead_edge, EdgeId(static_cast<std::uint32_t>(m.edge_capacity())), EdgeId{}};
  const std::vector<VertexId> bad_vertices = {
      dead_vertex, VertexId(static_cast<std::uint32_t>(m.vertex_capacity() + 1000)), VertexId{}};
  const std::vector<FaceId> bad_faces = {
      dead_face, FaceId(static_cast<std::uint32_t>(m.face_capacity() + 3)), FaceId{}};

  for (CornerId c : bad_corners) {
    const std::string name = to_string(c);
    expect_refused(m, "insert_edge(" + name + ", good)", name, [&] { m.insert_edge(c, good); });
    expect_refused(m, "insert_edge(good, " + name + ")", name, [&] { m.insert_edge(good, c); });
    expect_refused(m, "delete_edge_pair(" + name + ")", name, [&] { m.delete_edge_pair(c); });
  }
  for (EdgeId e : bad_edges) {
    const std::string name = to_string(e);
    expect_refused(m, "delete_edge(" + name + ")", name, [&] { m.delete_edge(e); });
  }
  for (VertexId v : bad_vertices) {
    const std::string name = to_string(v);
    expect_refused(m, "delete_vertex(" + name + ")", name, [&] { m.delete_vertex(v); });
    expect_refused(m, "add_rotation(" + name + ")", name, [&] { m.add_rotation(v); });
    expect_refused(m, "clean_rotations(" + name + ")", name, [&] { m.clean_rotations(v); });
  }
  for (FaceId f : bad_faces) {
    const std::string name = to_string(f);
    expect_refused(m, "set_bounding(" + name + ", true)", name, [&] { m.set_bounding(f, true); });
    expect_refused(m, "set_bounding(" + name + ", false)", name, [&] { m.set_bounding(f, false); });
    expect_refused(m, "is_bounding(" + name + ")", name, [&] { (void)m.is_bounding(f); });
  }
  // The names are the documented ones.
  EXPECT_EQ(to_string(CornerId(12)), "c12");
  EXPECT_EQ(to_string(CornerId{}), "c<invalid>");
}

TEST(DlflOperators, DeleteVertexOnlyTakesALonePointSphere) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  expect_refused(m, "delete_vertex of a vertex with edges", to_string(cube[3]),
                 [&] { m.delete_vertex(cube[3]); });

  const VertexId u = m.create_vertex({5, 0, 0});
  const AddRotationResult extra = m.add_rotation(u);
  expect_refused(m, "delete_vertex of a vertex with two rotations", to_string(u),
                 [&] { m.delete_vertex(u); });

  // Once its extra rotation is cleaned away, the lone point sphere can go.
  m.clean_rotations(u);
  EXPECT_FALSE(m.alive(extra.corner));
  ASSERT_EQ(rotation_count(m, u), 1u);
  const CornerId c = only_corner(m, u);
  const FaceId f = m.face(c);
  const auto before = counts(m);
  const auto version = m.topology_version();
  m.delete_vertex(u);
  EXPECT_FALSE(m.alive(u));
  EXPECT_FALSE(m.alive(c));
  EXPECT_FALSE(m.alive(f));
  EXPECT_GT(m.topology_version(), version);
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{before[0] - 1, before[1] - 1, before[2] - 1,
                                                 before[3], before[4] - 1}));
  expect_valid(m, "after delete_vertex");
  EXPECT_EQ(m.num_vertices(), 8u);
}

TEST(DlflOperators, InsertEdgeRefusesSelfLoopsAndASingleCorner) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const std::vector<CornerId> at0 = rotation_corners(m, m.first_rotation(cube[0]));
  ASSERT_EQ(at0.size(), 3u);
  // Two corners of one vertex: in different faces (would merge) ...
  expect_refused(m, "insert_edge between two corners of one vertex", to_string(cube[0]),
                 [&] { m.insert_edge(at0[0], at0[1]); });
  // ... in one face (the vertex repeats in the face after a spike joins it twice) ...
  const VertexId u = m.create_vertex({3, 0, 0});
  const CornerId pu = only_corner(m, u);
  const InsertEdgeResult spike = m.insert_edge(pu, at0[0]);
  ASSERT_FALSE(spike.split);
  const std::vector<CornerId> face = face_corners(m, spike.face_forward);
  std::vector<CornerId> on_v0;
  for (CornerId c : face) {
    if (m.vertex(c) == cube[0]) on_v0.push_back(c);
  }
  ASSERT_EQ(on_v0.size(), 2u);
  expect_refused(m, "insert_edge splitting a face between two corners of one vertex",
                 to_string(cube[0]), [&] { m.insert_edge(on_v0[0], on_v0[1]); });
  // ... and a corner of another rotation of the same vertex.
  const AddRotationResult r = m.add_rotation(cube[1]);
  const CornerId at1 = m.rotation_corner(m.first_rotation(cube[1]));
  expect_refused(m, "insert_edge between two rotations of one vertex", to_string(cube[1]),
                 [&] { m.insert_edge(r.corner, at1); });
  // One corner for both ends.
  expect_refused(m, "insert_edge(c, c)", to_string(at1), [&] { m.insert_edge(at1, at1); });
  expect_refused(m, "insert_edge(c, c) on a point sphere", to_string(r.corner),
                 [&] { m.insert_edge(r.corner, r.corner); });
  // A point sphere has no side to delete.
  expect_refused(m, "delete_edge_pair of a point sphere", to_string(r.corner),
                 [&] { m.delete_edge_pair(r.corner); });
}

// ---------------------------------------------------------------- splits and merges

TEST(DlflOperators, SplitBetweenNeighboursMakesADigonAndDeleteRestores) {
  Dlfl m;
  append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const Snapshot before = snapshot(m);
  const auto n0 = counts(m);
  const FaceId f = first_live_face(m);
  const CornerId c1 = m.first_corner(f);
  const CornerId c2 = m.next(c1);
  const EdgeId old_edge = m.edge(c1);

  const InsertEdgeResult r = m.insert_edge(c1, c2);
  expect_valid(m, "after the split");
  EXPECT_TRUE(r.split);
  EXPECT_FALSE(r.joined_existing);
  EXPECT_NE(r.edge, old_edge);
  EXPECT_EQ(m.edge_pair_count(r.edge), 1u);
  // f'' (holding c1 and side21) is the digon c1 -> side21; f' keeps the other four corners.
  EXPECT_EQ(face_valence(m, r.face_backward), 2u);
  EXPECT_EQ(face_valence(m, r.face_forward), 4u);
  EXPECT_EQ(m.face(c1), r.face_backward);
  EXPECT_EQ(m.face(c2), r.face_forward);
  EXPECT_EQ(m.next(c1), r.side21);
  EXPECT_EQ(m.next(r.side21), c1);
  EXPECT_EQ(m.next(r.side12), c2);
  const auto ends = edge_vertices(m, r.edge);
  const auto old_ends = edge_vertices(m, old_edge);
  EXPECT_EQ(std::minmax(ends.first, ends.second), std::minmax(old_ends.first, old_ends.second));
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{8, 26, 7, 13, 8}));
  EXPECT_EQ(part_keys(m), (std::vector<std::vector<std::int64_t>>{{8, 13, 7, 0, 2, 0}}));

  const DeleteEdgeResult d = m.delete_edge_pair(r.side12);
  expect_valid(m, "after the delete");
  EXPECT_FALSE(d.split);
  EXPECT_EQ(counts(m), n0);
  EXPECT_TRUE(snapshot(m) == before);
}

TEST(DlflOperators, MergeReusesPointSphereCornersAndDeleteGivesThemBack) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const VertexId u = m.create_vertex({3, 0, 0});
  const VertexId w = m.create_vertex({4, 0, 0});
  const CornerId pu = only_corner(m, u);
  const CornerId pw = only_corner(m, w);
  const CornerId c = m.rotation_corner(m.first_rotation(cube[0]));
  const Snapshot before = snapshot(m);

  // Point sphere to point sphere: both corners are reused, one face of two corners is left.
  const InsertEdgeResult a = m.insert_edge(pu, pw);
  expect_valid(m, "after joining two point spheres");
  EXPECT_FALSE(a.split);
  EXPECT_EQ(a.side12, pu);
  EXPECT_EQ(a.side21, pw);
  EXPECT_EQ(face_valence(m, a.face_forward), 2u);
  // Point sphere to a corner of the cube: one new corner at the cube's vertex.
  const auto n1 = counts(m);
  const InsertEdgeResult b = m.insert_edge(c, pu);
  expect_valid(m, "after joining the pair to the cube");
  EXPECT_FALSE(b.split);
  EXPECT_NE(b.side12, c);
  EXPECT_NE(b.side21, pu);  // pu is no longer a point sphere
  EXPECT_EQ(m.num_corners(), n1[1] + 2);
  EXPECT_EQ(m.num_faces(), n1[2] - 1);
  EXPECT_EQ(vertex_valence(m, cube[0]), 4u);

  m.delete_edge_pair(b.side12);
  m.delete_edge_pair(a.side21);
  expect_valid(m, "after the deletes");
  EXPECT_TRUE(m.is_point_sphere(pu));
  EXPECT_TRUE(m.is_point_sphere(pw));
  EXPECT_TRUE(snapshot(m) == before);
}

// ---------------------------------------------------------------- labels (procedures 1 and 2)

TEST(DlflLabels, SplitOfALabelledFaceLabelsOnlyTheChosenSide) {
  for (const LabelSide side : {LabelSide::Forward, LabelSide::Backward}) {
    SCOPED_TRACE(side == LabelSide::Forward ? "Forward" : "Backward");
    Dlfl m;
    const Square sq = add_square(m, {0, 0, 0});
    ASSERT_TRUE(m.is_bounding(sq.hole));
    ASSERT_FALSE(m.is_bounding(sq.quad));
    const Snapshot before = snapshot(m);
    const CornerId c1 = corner_of(m, sq.hole, 0);
    const CornerId c2 = corner_of(m, sq.hole, 2);
    InsertEdgeOptions options;
    options.label_side = side;
    const InsertEdgeResult r = m.insert_edge(c1, c2, options);
    expect_valid(m, "after the split");
    ASSERT_TRUE(r.split);
    EXPECT_EQ(m.face(c2), r.face_forward);
    EXPECT_EQ(m.face(c1), r.face_backward);
    EXPECT_EQ(m.is_bounding(r.face_forward), side == LabelSide::Forward);
    EXPECT_EQ(m.is_bounding(r.face_backward), side == LabelSide::Backward);
    EXPECT_FALSE(m.is_bounding(sq.quad));
    EXPECT_EQ(boundary_loops(m).size(), 1u);
    // The delete merges a labelled and an unlabelled face: labelled, as before the insert.
    const DeleteEdgeResult d = m.delete_edge_pair(r.side21);
    expect_valid(m, "after the delete");
    EXPECT_FALSE(d.split);
    EXPECT_TRUE(m.is_bounding(d.face_a));
    EXPECT_TRUE(snapshot(m) == before);
  }
}

TEST(DlflLabels, SplitOfAnUnlabelledFaceLabelsNeitherSide) {
  for (const LabelSide side : {LabelSide::Forward, LabelSide::Backward}) {
    Dlfl m;
    const Square sq = add_square(m, {0, 0, 0});
    InsertEdgeOptions options;
    options.label_side = side;
    const InsertEdgeResult r =
        m.insert_edge(corner_of(m, sq.quad, 1), corner_of(m, sq.quad, 3), options);
    ASSERT_TRUE(r.split);
    EXPECT_FALSE(m.is_bounding(r.face_forward));
    EXPECT_FALSE(m.is_bounding(r.face_backward));
    EXPECT_TRUE(m.is_bounding(sq.hole));
  }
}

TEST(DlflLabels, InsertMergeIsLabelledWhenEitherFaceWas) {
  struct Case {
    bool hole_a, hole_b, labelled;
  };
  for (const Case k : {Case{true, false, true}, Case{false, true, true}, Case{false, false, false},
                       Case{true, true, true}}) {
    SCOPED_TRACE(std::string("A ") + (k.hole_a ? "hole" : "quad") + ", B " +
                 (k.hole_b ? "hole" : "quad"));
    Dlfl m;
    const Square a = add_square(m, {0, 0, 0});
    const Square b = add_square(m, {3, 0, 0});
    const FaceId fa = k.hole_a ? a.hole : a.quad;
    const FaceId fb = k.hole_b ? b.hole : b.quad;
    const InsertEdgeResult r = m.insert_edge(corner_of(m, fa, 0), corner_of(m, fb, 0));
    expect_valid(m, "after the merge");
    ASSERT_FALSE(r.split);
    EXPECT_EQ(r.face_forward, r.face_backward);
    EXPECT_EQ(face_valence(m, r.face_forward), 10u);
    EXPECT_EQ(m.is_bounding(r.face_forward), k.labelled);
    EXPECT_EQ(m.num_faces(), 3u);
  }
}

TEST(DlflLabels, DeleteSplitOfALabelledFaceLabelsBothPieces) {
  // A bridge inside a labelled face: the merged face of a hole and an unlabelled quad.
  Dlfl m;
  const Square a = add_square(m, {0, 0, 0});
  const Square b = add_square(m, {3, 0, 0});
  const CornerId in_b_quad = corner_of(m, b.quad, 1);
  const CornerId in_b_hole = corner_of(m, b.hole, 0);
  const InsertEdgeResult r = m.insert_edge(corner_of(m, a.hole, 0), corner_of(m, b.quad, 0));
  ASSERT_TRUE(m.is_bounding(r.face_forward));
  const DeleteEdgeResult d = m.delete_edge_pair(r.side12);
  expect_valid(m, "after the delete");
  ASSERT_TRUE(d.split);
  EXPECT_NE(d.face_a, d.face_b);
  EXPECT_TRUE(m.is_bounding(d.face_a));
  EXPECT_TRUE(m.is_bounding(d.face_b));
  // So the quad of B is labelled now (the documented exception to the exact inverse).
  EXPECT_TRUE(m.is_bounding(m.face(in_b_quad)));
  EXPECT_TRUE(m.is_bounding(m.face(in_b_hole)));
  EXPECT_EQ(face_valence(m, m.face(in_b_quad)), 4u);
  EXPECT_EQ(boundary_loops(m).size(), 3u);

  // A spike into a labelled face: its point sphere comes back labelled.
  Dlfl s;
  const Square c = add_square(s, {0, 0, 0});
  const VertexId u = s.create_vertex({0.5, 0.5, 0});
  const CornerId pu = only_corner(s, u);
  const CornerId in_hole = corner_of(s, c.hole, 1);
  const InsertEdgeResult spike = s.insert_edge(in_hole, pu);
  ASSERT_TRUE(s.is_bounding(spike.face_forward));
  const DeleteEdgeResult back = s.delete_edge_pair(spike.side12);
  expect_valid(s, "after deleting the spike");
  EXPECT_TRUE(back.split);
  EXPECT_TRUE(s.is_point_sphere(pu));
  EXPECT_TRUE(s.is_bounding(s.face(pu)));
  EXPECT_TRUE(s.is_bounding(s.face(in_hole)));
  EXPECT_EQ(face_valence(s, s.face(in_hole)), 4u);
  // A point sphere is not a boundary loop: only the hole has sides.
  EXPECT_EQ(boundary_loops(s), std::vector<FaceId>{s.face(in_hole)});
}

TEST(DlflLabels, DeleteMergeIsLabelledWhenEitherFaceWas) {
  // A boundary edge of the square: its sides are in the quad and in the hole.
  Dlfl m;
  const Square sq = add_square(m, {0, 0, 0});
  const CornerId side = corner_of(m, sq.quad, 0);
  const DeleteEdgeResult d = m.delete_edge_pair(side);
  expect_valid(m, "after the delete");
  EXPECT_FALSE(d.split);
  EXPECT_EQ(d.face_a, d.face_b);
  EXPECT_TRUE(m.is_bounding(d.face_a));
  EXPECT_EQ(m.num_faces(), 1u);
  EXPECT_EQ(face_valence(m, d.face_a), 6u);

  // An edge of the cube: two unlabelled faces stay unlabelled.
  Dlfl c;
  append_oriented_manifold(c, cube_mesh({0, 0, 0}, 1.0));
  ASSERT_TRUE(c.alive(EdgeId(0)));
  const DeleteEdgeResult e = c.delete_edge(EdgeId(0));
  EXPECT_FALSE(e.split);
  EXPECT_FALSE(c.is_bounding(e.face_a));
  EXPECT_EQ(face_valence(c, e.face_a), 6u);
}

TEST(DlflLabels, OppositelyOrientedLabelledFacesAreNotMerged) {
  Dlfl m;
  const Square a = add_square(m, {0, 0, 0});
  const Square b = add_square(m, {3, 0, 0});
  // B labels its quad (normal +z) instead of its hole; A's hole has normal -z.
  m.set_bounding(b.hole, false);
  m.set_bounding(b.quad, true);
  const CornerId ca = corner_of(m, a.hole, 0);
  const CornerId cb = corner_of(m, b.quad, 0);
  expect_refused<LabelOrientationError>(m, "merging labelled faces of opposite orientation",
                                        to_string(a.hole), [&] { m.insert_edge(ca, cb); });
  expect_refused<LabelOrientationError>(m, "the same, ends swapped", to_string(b.quad),
                                        [&] { m.insert_edge(cb, ca); });

  // Same orientation: accepted.
  const Square c = add_square(m, {6, 0, 0});
  const InsertEdgeResult same = m.insert_edge(ca, corner_of(m, c.hole, 0));
  expect_valid(m, "after merging two holes");
  EXPECT_FALSE(same.split);
  EXPECT_TRUE(m.is_bounding(same.face_forward));
  m.delete_edge_pair(same.side12);
  // The check can be switched off.
  InsertEdgeOptions options;
  options.check_label_orientation = false;
  const InsertEdgeResult r = m.insert_edge(ca, cb, options);
  expect_valid(m, "after the unchecked merge");
  EXPECT_FALSE(r.split);
  EXPECT_TRUE(m.is_bounding(r.face_forward));
}

// ---------------------------------------------------------------- rotations

TEST(DlflRotations, AddRotationAppendsPointSpheresAndCleanRemovesThem) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const VertexId v = cube[0];
  const Snapshot before = snapshot(m);
  const auto n0 = counts(m);
  const RotationId first = m.first_rotation(v);

  const AddRotationResult r1 = m.add_rotation(v);
  const AddRotationResult r2 = m.add_rotation(v);
  expect_valid(m, "after add_rotation");
  EXPECT_EQ(rotation_count(m, v), 3u);
  EXPECT_EQ(rotations_of(m, v), (std::vector<RotationId>{first, r1.rotation, r2.rotation}));
  for (const AddRotationResult& r : {r1, r2}) {
    EXPECT_TRUE(m.is_point_sphere(r.corner));
    EXPECT_EQ(m.vertex(r.corner), v);
    EXPECT_EQ(m.face(r.corner), r.face);
    EXPECT_EQ(m.rotation_corner(r.rotation), r.corner);
  }
  EXPECT_EQ(vertex_valence(m, v), 3u);
  const auto around = faces_around_vertex(m, v);
  ASSERT_EQ(around.size(), 3u);
  EXPECT_EQ(around[0].size(), 3u);
  EXPECT_EQ(around[1], std::vector<FaceId>{r1.face});
  EXPECT_EQ(around[2], std::vector<FaceId>{r2.face});
  EXPECT_EQ(non_manifold_vertices(m), std::vector<VertexId>{v});
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{8, 26, 8, 12, 10}));

  const auto version = m.topology_version();
  m.clean_rotations(v);
  expect_valid(m, "after clean_rotations");
  EXPECT_GT(m.topology_version(), version);
  EXPECT_EQ(rotations_of(m, v), std::vector<RotationId>{first});
  EXPECT_FALSE(m.alive(r1.corner));
  EXPECT_FALSE(m.alive(r2.face));
  EXPECT_TRUE(non_manifold_vertices(m).empty());
  EXPECT_EQ(counts(m), n0);
  EXPECT_TRUE(snapshot(m) == before);

  // Nothing to clean: nothing changes.
  m.clean_rotations(v);
  EXPECT_TRUE(snapshot(m) == before);
  EXPECT_EQ(counts(m), n0);
}

TEST(DlflRotations, CleanKeepsTheFirstWhenAllArePointSpheres) {
  Dlfl m;
  const VertexId u = m.create_vertex({1, 2, 3});
  const RotationId first = m.first_rotation(u);
  const CornerId kept = m.rotation_corner(first);
  const AddRotationResult a = m.add_rotation(u);
  const AddRotationResult b = m.add_rotation(u);
  ASSERT_EQ(rotation_count(m, u), 3u);
  m.clean_rotations(u);
  expect_valid(m, "after clean_rotations");
  EXPECT_EQ(rotations_of(m, u), std::vector<RotationId>{first});
  EXPECT_TRUE(m.alive(kept));
  EXPECT_TRUE(m.is_point_sphere(kept));
  EXPECT_FALSE(m.alive(a.corner));
  EXPECT_FALSE(m.alive(b.corner));
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{1, 1, 1, 0, 1}));
  m.delete_vertex(u);
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{0, 0, 0, 0, 0}));
  expect_valid(m, "after delete_vertex");
}

TEST(DlflRotations, CleanRemovesAFirstPointSphereWhenAnotherRotationHasEdges) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  const VertexId u = m.create_vertex({3, 0, 0});
  const RotationId first = m.first_rotation(u);
  const CornerId sphere = m.rotation_corner(first);
  const AddRotationResult second = m.add_rotation(u);
  const InsertEdgeResult r =
      m.insert_edge(second.corner, m.rotation_corner(m.first_rotation(cube[1])));
  ASSERT_FALSE(r.split);
  const AddRotationResult third = m.add_rotation(u);
  ASSERT_EQ(rotation_count(m, u), 3u);
  m.clean_rotations(u);
  expect_valid(m, "after clean_rotations");
  EXPECT_EQ(rotations_of(m, u), std::vector<RotationId>{second.rotation});
  EXPECT_EQ(m.first_rotation(u), second.rotation);
  EXPECT_FALSE(m.alive(sphere));
  EXPECT_FALSE(m.alive(third.corner));
  EXPECT_EQ(vertex_valence(m, u), 1u);
}

TEST(DlflRotations, SecondPairOfAnEdgeInTheSameRotationsIsNotJoined) {
  // a-b joined in rotations (Ra, Rb1); a second pair in (Ra, Rb2) makes a non-manifold edge.
  // A further a-b edge in (Ra, Rb2) is a parallel edge of that sheet: joining it to the
  // non-manifold edge would give the edge two pairs in the same rotations.
  Dlfl m;
  const VertexId a = m.create_vertex({0, 0, 0});
  const VertexId b = m.create_vertex({1, 0, 0});
  const CornerId ca = only_corner(m, a);
  const CornerId cb = only_corner(m, b);
  const InsertEdgeResult first = m.insert_edge(ca, cb);
  const CornerId pb = m.add_rotation(b).corner;
  const InsertEdgeResult second = m.insert_edge(ca, pb);
  expect_valid(m, "after the second pair");
  ASSERT_TRUE(second.joined_existing);
  EXPECT_EQ(second.edge, first.edge);
  EXPECT_EQ(m.edge_pair_count(first.edge), 2u);
  const Snapshot before = snapshot(m);

  const InsertEdgeResult third = m.insert_edge(ca, pb);
  expect_valid(m, "after an a-b edge in the rotations of the second pair");
  EXPECT_TRUE(third.split);
  EXPECT_EQ(m.edge_pair_count(first.edge), 2u);
  m.delete_edge_pair(third.side12);
  expect_valid(m, "after its delete");
  EXPECT_TRUE(snapshot(m) == before);
}

// ---------------------------------------------------------------- compact

TEST(DlflCompact, DenseHandlesSameTopologyAndPropertiesFollow) {
  Dlfl m;
  append_oriented_manifold(m, torus_mesh(3.0, 1.0, 8, 6, true));
  append_oriented_manifold(m, moved(grid_mesh(3, 3, 1.0, false), {10, 0, 0}));
  auto& id = m.vertex_properties().add<int>("id", -1);
  auto& tag = m.face_properties().add<int>("tag", -7);
  auto& serial = m.corner_properties().add<std::uint32_t>("serial", 0);
  std::vector<VertexId> extra;
  for (int k = 0; k < 5; ++k)
    extra.push_back(m.create_vertex({-1.0 - k, 0, 0}));
  EXPECT_EQ(id[extra[0]], -1);
  for (std::uint32_t i = 0; i < m.vertex_capacity(); ++i)
    id[VertexId(i)] = static_cast<int>(i);
  for (std::uint32_t i = 0; i < m.face_capacity(); ++i)
    tag[FaceId(i)] = static_cast<int>(i);

  // Random deletions (and some creations that reuse the freed slots).
  std::mt19937 rng(7);
  for (int k = 0; k < 40; ++k) {
    EdgeId e(static_cast<std::uint32_t>(rng() % m.edge_capacity()));
    if (m.alive(e)) m.delete_edge(e);
  }
  for (int k : {0, 2, 3})
    m.delete_vertex(extra[static_cast<std::size_t>(k)]);
  const VertexId fresh = m.create_vertex({-5, -5, -5});
  EXPECT_EQ(id[fresh], -1);  // a reused slot takes the default again
  EXPECT_EQ(tag[m.face(only_corner(m, fresh))], -7);
  m.add_rotation(VertexId(3));
  expect_valid(m, "before compact");
  ASSERT_GT(m.corner_capacity(), m.num_corners());
  ASSERT_GT(m.face_capacity(), m.num_faces());
  ASSERT_GT(m.edge_capacity(), m.num_edges());

  // What must survive: every vertex's (id, position), every face's tag keyed by its corners.
  std::uint32_t next_serial = 1;
  for (std::uint32_t i = 0; i < m.corner_capacity(); ++i) {
    if (m.alive(CornerId(i))) serial[CornerId(i)] = next_serial++;
  }
  auto vertex_data = [&] {
    std::multiset<std::pair<int, std::vector<double>>> out;
    for (std::uint32_t i = 0; i < m.vertex_capacity(); ++i) {
      const VertexId v(i);
      if (!m.alive(v)) continue;
      const auto& p = m.position(v);
      out.emplace(id[v], std::vector<double>{p.x, p.y, p.z});
    }
    return out;
  };
  auto face_data = [&] {
    std::map<Cycle, std::pair<int, bool>> out;
    for (std::uint32_t i = 0; i < m.face_capacity(); ++i) {
      const FaceId f(i);
      if (!m.alive(f)) continue;
      Cycle serials;
      for (CornerId c : face_corners(m, f))
        serials.push_back(serial[c]);
      out[canonical(serials)] = {tag[f], m.is_bounding(f)};
    }
    return out;
  };
  const auto vertices_before = vertex_data();
  const auto faces_before = face_data();
  const MeshStatistics stats = mesh_statistics(m);
  const auto parts_before = part_keys(m);

  m.compact();
  expect_valid(m, "after compact");
  EXPECT_EQ(m.vertex_capacity(), m.num_vertices());
  EXPECT_EQ(m.corner_capacity(), m.num_corners());
  EXPECT_EQ(m.face_capacity(), m.num_faces());
  EXPECT_EQ(m.edge_capacity(), m.num_edges());
  EXPECT_EQ(m.rotation_capacity(), m.num_rotations());
  EXPECT_EQ(id.size(), m.vertex_capacity());
  EXPECT_EQ(tag.size(), m.face_capacity());
  EXPECT_EQ(serial.size(), m.corner_capacity());
  const MeshStatistics after = mesh_statistics(m);
  EXPECT_EQ(after.vertices, stats.vertices);
  EXPECT_EQ(after.edges, stats.edges);
  EXPECT_EQ(after.faces, stats.faces);
  EXPECT_EQ(after.corners, stats.corners);
  EXPECT_EQ(after.rotations, stats.rotations);
  EXPECT_EQ(after.bounding_faces, stats.bounding_faces);
  EXPECT_EQ(after.point_spheres, stats.point_spheres);
  EXPECT_EQ(after.non_manifold_vertices, stats.non_manifold_vertices);
  EXPECT_EQ(part_keys(m), parts_before);
  EXPECT_EQ(vertex_data(), vertices_before);
  EXPECT_EQ(face_data(), faces_before);

  // New elements take the default values.
  const VertexId v = m.create_vertex({1, 1, 1});
  EXPECT_EQ(id[v], -1);
  EXPECT_EQ(tag[m.face(only_corner(m, v))], -7);
  EXPECT_EQ(serial[only_corner(m, v)], 0u);
  CornerId with_edge;
  for (std::uint32_t i = 0; i < m.corner_capacity() && !with_edge.valid(); ++i) {
    if (!m.is_point_sphere(CornerId(i))) with_edge = CornerId(i);
  }
  ASSERT_TRUE(with_edge.valid());
  const InsertEdgeResult r = m.insert_edge(with_edge, only_corner(m, v));
  EXPECT_NE(r.side12, with_edge);
  EXPECT_EQ(serial[r.side12], 0u);
  EXPECT_NE(serial[with_edge], 0u);
  expect_valid(m, "after new elements");
}

// ---------------------------------------------------------------- queries

TEST(DlflQueries, TorusIsGenusOne) {
  const Dlfl m = build_oriented_manifold(torus_mesh(3.0, 1.0, 6, 4, true));
  expect_valid(m, "torus");
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{24, 144, 48, 72, 24}));
  for (std::uint32_t i = 0; i < m.face_capacity(); ++i) {
    if (m.alive(FaceId(i))) {
      EXPECT_EQ(face_valence(m, FaceId(i)), 3u) << to_string(FaceId(i));
    }
  }
  for (std::uint32_t i = 0; i < m.vertex_capacity(); ++i) {
    EXPECT_EQ(vertex_valence(m, VertexId(i)), 6u);
    const auto around = faces_around_vertex(m, VertexId(i));
    ASSERT_EQ(around.size(), 1u);
    EXPECT_EQ(around[0].size(), 6u);
    EXPECT_EQ(std::set<FaceId>(around[0].begin(), around[0].end()).size(), 6u);
  }
  for (std::uint32_t i = 0; i < m.edge_capacity(); ++i) {
    const auto faces = edge_faces(m, EdgeId(i));
    ASSERT_EQ(faces.size(), 2u);
    EXPECT_NE(faces[0], faces[1]);
  }
  EXPECT_TRUE(boundary_loops(m).empty());
  EXPECT_TRUE(non_manifold_edges(m).empty());
  const auto parts = connected_parts(m);
  ASSERT_EQ(parts.size(), 1u);
  const PartTopology t = part_topology(m, parts[0]);
  EXPECT_EQ(t.vertices, 24u);
  EXPECT_EQ(t.edges, 72u);
  EXPECT_EQ(t.faces, 48u);
  EXPECT_EQ(t.rings, 0u);
  EXPECT_EQ(t.euler_characteristic, 0);
  EXPECT_EQ(t.genus, 1);
}

TEST(DlflQueries, GridIsADiscWithOneRing) {
  Dlfl m;
  const auto v = append_oriented_manifold(m, grid_mesh(3, 3, 1.0, false));
  expect_valid(m, "grid");
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{16, 48, 10, 24, 16}));
  const auto loops = boundary_loops(m);
  ASSERT_EQ(loops.size(), 1u);
  EXPECT_EQ(face_valence(m, loops[0]), 12u);
  // Corner, side and inner vertices of the 4 x 4 lattice.
  EXPECT_EQ(vertex_valence(m, v[0]), 2u);
  EXPECT_EQ(vertex_valence(m, v[1]), 3u);
  EXPECT_EQ(vertex_valence(m, v[5]), 4u);
  const auto corner = faces_around_vertex(m, v[0]);
  ASSERT_EQ(corner.size(), 1u);
  ASSERT_EQ(corner[0].size(), 2u);
  EXPECT_EQ(std::count(corner[0].begin(), corner[0].end(), loops[0]), 1);
  const auto inner = faces_around_vertex(m, v[5]);
  ASSERT_EQ(inner.size(), 1u);
  EXPECT_EQ(inner[0].size(), 4u);
  EXPECT_EQ(std::count(inner[0].begin(), inner[0].end(), loops[0]), 0);
  const auto parts = connected_parts(m);
  ASSERT_EQ(parts.size(), 1u);
  const PartTopology t = part_topology(m, parts[0]);
  EXPECT_EQ(t.vertices, 16u);
  EXPECT_EQ(t.edges, 24u);
  EXPECT_EQ(t.faces, 9u);
  EXPECT_EQ(t.rings, 1u);
  EXPECT_EQ(t.euler_characteristic, 1);
  EXPECT_EQ(t.genus, 0);
}

TEST(DlflQueries, TubeHasTwoRings) {
  const Dlfl m = build_oriented_manifold(tube_mesh(1.0, 2.0, 6, 2));
  expect_valid(m, "tube");
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{18, 60, 14, 30, 18}));
  const auto loops = boundary_loops(m);
  ASSERT_EQ(loops.size(), 2u);
  EXPECT_EQ(face_valence(m, loops[0]), 6u);
  EXPECT_EQ(face_valence(m, loops[1]), 6u);
  const auto parts = connected_parts(m);
  ASSERT_EQ(parts.size(), 1u);
  const PartTopology t = part_topology(m, parts[0]);
  EXPECT_EQ(t.vertices, 18u);
  EXPECT_EQ(t.edges, 30u);
  EXPECT_EQ(t.faces, 12u);
  EXPECT_EQ(t.rings, 2u);
  EXPECT_EQ(t.euler_characteristic, 0);
  EXPECT_EQ(t.genus, 0);
}

TEST(DlflQueries, NonManifoldEdgeHasFourFaces) {
  Dlfl m;
  const auto cube = append_oriented_manifold(m, cube_mesh({0, 0, 0}, 1.0));
  // Cube vertices 0 and 1 share an edge; join them again in new rotations of both.
  EdgeId shared;
  for (CornerId c : rotation_corners(m, m.first_rotation(cube[0]))) {
    if (m.vertex(m.next(c)) == cube[1]) shared = m.edge(c);
  }
  ASSERT_TRUE(shared.valid());
  const std::vector<FaceId> cube_faces = edge_faces(m, shared);
  const CornerId pu = m.add_rotation(cube[0]).corner;
  const CornerId pw = m.add_rotation(cube[1]).corner;
  const InsertEdgeResult r = m.insert_edge(pu, pw);
  expect_valid(m, "after the second pair");
  EXPECT_TRUE(r.joined_existing);
  EXPECT_EQ(r.edge, shared);
  EXPECT_EQ(m.edge_pair_count(shared), 2u);
  EXPECT_EQ(m.num_edges(), 12u);
  const std::vector<FaceId> faces = edge_faces(m, shared);
  ASSERT_EQ(faces.size(), 4u);
  EXPECT_EQ(std::vector<FaceId>(faces.begin(), faces.begin() + 2), cube_faces);
  EXPECT_EQ(faces[2], r.face_forward);
  EXPECT_EQ(faces[3], r.face_forward);
  EXPECT_EQ(non_manifold_edges(m), std::vector<EdgeId>{shared});
  EXPECT_EQ(non_manifold_vertices(m), (std::vector<VertexId>{cube[0], cube[1]}));
  EXPECT_EQ(vertex_valence(m, cube[0]), 4u);
  const auto around = faces_around_vertex(m, cube[0]);
  ASSERT_EQ(around.size(), 2u);
  EXPECT_EQ(around[0].size(), 3u);
  EXPECT_EQ(around[1], std::vector<FaceId>{r.face_forward});
  // The cube and a two-corner sphere meeting along the edge.
  EXPECT_EQ(part_keys(m),
            (std::vector<std::vector<std::int64_t>>{{2, 1, 1, 0, 2, 0}, {8, 12, 6, 0, 2, 0}}));

  // delete_edge removes every pair: the cube loses an edge, the sphere falls apart.
  m.delete_edge(shared);
  expect_valid(m, "after delete_edge");
  EXPECT_FALSE(m.alive(shared));
  EXPECT_TRUE(m.is_point_sphere(pu));
  EXPECT_TRUE(m.is_point_sphere(pw));
  EXPECT_NE(m.face(pu), m.face(pw));
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{8, 24, 7, 11, 10}));
}

TEST(DlflQueries, TwoTetrahedraSharingAVertex) {
  Dlfl m;
  const auto first = append_oriented_manifold(m, tetrahedron_mesh());
  BuildOptions join;
  join.join_vertices.assign(4, VertexId{});
  join.join_vertices[0] = first[0];
  const auto second = append_oriented_manifold(m, moved(tetrahedron_mesh(), {0, 0, 0}), join);
  expect_valid(m, "two tetrahedra");
  EXPECT_EQ(second[0], first[0]);
  EXPECT_EQ(counts(m), (std::vector<std::size_t>{7, 24, 8, 12, 8}));
  EXPECT_EQ(rotation_count(m, first[0]), 2u);
  EXPECT_EQ(vertex_valence(m, first[0]), 6u);
  const auto around = faces_around_vertex(m, first[0]);
  ASSERT_EQ(around.size(), 2u);
  EXPECT_EQ(around[0].size(), 3u);
  EXPECT_EQ(around[1].size(), 3u);
  EXPECT_EQ(non_manifold_vertices(m), std::vector<VertexId>{first[0]});
  EXPECT_TRUE(non_manifold_edges(m).empty());
  EXPECT_EQ(part_keys(m),
            (std::vector<std::vector<std::int64_t>>{{4, 6, 4, 0, 2, 0}, {4, 6, 4, 0, 2, 0}}));
}

}  // namespace
}  // namespace bisturi
