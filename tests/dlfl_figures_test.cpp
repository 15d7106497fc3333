// The seed's figures, step by step with the DLFL operators: the closed tetrahedron of figure 35,
// the open chalice of figure 38, labelled faces in the same and opposite orientations (figure
// 39), deleting an edge next to a labelled face (figure 40), two tetrahedra joined at a vertex
// (figures 41-42) and two cubes sharing an edge (figure 14). validate() runs after every step.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <set>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"

namespace bisturi {
namespace {

#define EXPECT_VALID(mesh)                          \
  do {                                              \
    const auto report_ = validate(mesh);            \
    EXPECT_TRUE(report_.ok()) << report_.summary(); \
  } while (0)

/// The one corner of vertex v in face f (the figures name corners that way: "v1 (f2)").
CornerId corner_in(const Dlfl& mesh, VertexId v, FaceId f) {
  CornerId found;
  int count = 0;
  for (CornerId c : face_corners(mesh, f)) {
    if (mesh.vertex(c) == v) {
      found = c;
      ++count;
    }
  }
  EXPECT_EQ(count, 1) << to_string(v) << " appears " << count << " times in " << to_string(f);
  return found;
}

/// The point sphere of a vertex that has no edges yet.
CornerId sphere(const Dlfl& mesh, VertexId v) {
  return mesh.rotation_corner(mesh.first_rotation(v));
}

std::set<VertexId> vertex_set(const Dlfl& mesh, FaceId f) {
  const auto vs = face_vertices(mesh, f);
  return {vs.begin(), vs.end()};
}

std::vector<FaceId> live_faces(const Dlfl& mesh) {
  std::vector<FaceId> out;
  for (std::uint32_t i = 0; i < mesh.face_capacity(); ++i) {
    if (mesh.alive(FaceId(i))) out.emplace_back(i);
  }
  return out;
}

/// Figure 35 (plain operators) or figure 38 (with v1's point sphere labelled first). Returns
/// the four vertices.
std::array<VertexId, 4> build_chalice_steps(Dlfl& mesh, bool label_first) {
  std::array<VertexId, 4> v{};
  // Step 1: four CreateVertex (and, in figure 38, the label on f1).
  for (auto& x : v)
    x = mesh.create_vertex();
  mesh.set_position(v[0], {0, 0, 0});
  mesh.set_position(v[1], {1, 0, 1});
  mesh.set_position(v[2], {-1, 0, 1});
  mesh.set_position(v[3], {0, 1, 1});
  if (label_first) mesh.set_bounding(mesh.face(sphere(mesh, v[0])), true);
  EXPECT_VALID(mesh);
  // Step 2: v1 (f1) - v2 (f2): two point spheres join in one face.
  auto r = mesh.insert_edge(sphere(mesh, v[0]), sphere(mesh, v[1]));
  EXPECT_FALSE(r.split);
  EXPECT_EQ(face_valence(mesh, r.face_forward), 2u);
  EXPECT_VALID(mesh);
  // Step 3: v1 (f1) - v3 (f3): merge, v1 repeats.
  FaceId f1 = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, v[0], f1), sphere(mesh, v[2]));
  EXPECT_FALSE(r.split);
  EXPECT_EQ(face_valence(mesh, r.face_forward), 4u);
  EXPECT_VALID(mesh);
  // Step 4: v3 (f1) - v2 (f1): the face splits in two opposite triangles.
  f1 = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, v[2], f1), corner_in(mesh, v[1], f1));
  EXPECT_TRUE(r.split);
  EXPECT_EQ(face_valence(mesh, r.face_forward), 3u);
  EXPECT_EQ(face_valence(mesh, r.face_backward), 3u);
  EXPECT_VALID(mesh);
  // Step 5: v1 (f2) - v4 (f4), f2 being the face that keeps the insertion's direction.
  const FaceId f2 = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, v[0], f2), sphere(mesh, v[3]));
  EXPECT_FALSE(r.split);
  EXPECT_VALID(mesh);
  // Step 6: v2 (f2) - v4 (f2): f2 now runs around the two closed faces.
  const FaceId f2b = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, v[1], f2b), corner_in(mesh, v[3], f2b));
  EXPECT_TRUE(r.split);
  EXPECT_VALID(mesh);
  // Step 7: v4 (f2) - v3 (f2).
  const FaceId f2c = r.face_forward;
  EXPECT_EQ(face_valence(mesh, f2c), 4u);
  r = mesh.insert_edge(corner_in(mesh, v[3], f2c), corner_in(mesh, v[2], f2c));
  EXPECT_TRUE(r.split);
  EXPECT_VALID(mesh);
  return v;
}

TEST(SeedFigure35, PlainOperatorsCloseTheChaliceIntoATetrahedron) {
  Dlfl mesh;
  build_chalice_steps(mesh, false);
  const auto s = mesh_statistics(mesh);
  EXPECT_EQ(s.vertices, 4u);
  EXPECT_EQ(s.edges, 6u);
  EXPECT_EQ(s.faces, 4u);
  EXPECT_EQ(s.bounding_faces, 0u);
  for (FaceId f : live_faces(mesh))
    EXPECT_EQ(face_valence(mesh, f), 3u);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 2);
  EXPECT_EQ(s.parts[0].genus, 0);
}

TEST(SeedFigure38, LabelsMakeTheOpenChalice) {
  Dlfl mesh;
  const auto v = build_chalice_steps(mesh, true);
  const auto s = mesh_statistics(mesh);
  const auto loops = boundary_loops(mesh);
  ASSERT_EQ(loops.size(), 1u);
  // The labelled face is the top: the triangle away from the apex v1.
  EXPECT_EQ(vertex_set(mesh, loops[0]), (std::set<VertexId>{v[1], v[2], v[3]}));
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].faces, 3u);
  EXPECT_EQ(s.parts[0].rings, 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 1);
  EXPECT_EQ(s.parts[0].genus, 0);
  // Every real face touches the apex.
  for (FaceId f : live_faces(mesh)) {
    if (!mesh.is_bounding(f)) {
      EXPECT_TRUE(vertex_set(mesh, f).count(v[0]));
    }
  }
}

TEST(SeedFigure38, LabelDirectionIsAParameter) {
  // Splitting the labelled face of figure 38 step 4 with LabelSide::Backward labels f1''.
  Dlfl mesh;
  std::array<VertexId, 3> v{};
  for (auto& x : v)
    x = mesh.create_vertex();
  mesh.set_bounding(mesh.face(sphere(mesh, v[0])), true);
  auto r = mesh.insert_edge(sphere(mesh, v[0]), sphere(mesh, v[1]));
  r = mesh.insert_edge(corner_in(mesh, v[0], r.face_forward), sphere(mesh, v[2]));
  const FaceId f = r.face_forward;
  InsertEdgeOptions backward;
  backward.label_side = LabelSide::Backward;
  r = mesh.insert_edge(corner_in(mesh, v[2], f), corner_in(mesh, v[1], f), backward);
  EXPECT_VALID(mesh);
  EXPECT_FALSE(mesh.is_bounding(r.face_forward));
  EXPECT_TRUE(mesh.is_bounding(r.face_backward));
}

/// A unit quad in the z = 0 plane at x offset dx, counter-clockwise seen from +z, with its
/// boundary face labelled (the builder's hole face). Returns the 4 vertices.
std::vector<VertexId> labelled_quad(Dlfl& mesh, double dx) {
  PolygonMesh quad;
  quad.positions = {{dx, 0, 0}, {dx + 1, 0, 0}, {dx + 1, 1, 0}, {dx, 1, 0}};
  quad.add_face({0, 1, 2, 3});
  return append_oriented_manifold(mesh, quad);
}

FaceId face_with(const Dlfl& mesh, VertexId v, bool bounding) {
  for (FaceId f : live_faces(mesh)) {
    if (mesh.is_bounding(f) == bounding && vertex_set(mesh, f).count(v)) return f;
  }
  return FaceId{};
}

TEST(SeedFigure39, SameOrientationLabelsGiveOneRingAroundTheBorder) {
  Dlfl mesh;
  const auto a = labelled_quad(mesh, 0.0);
  const auto b = labelled_quad(mesh, 2.0);
  EXPECT_VALID(mesh);
  // Join the two rings at a1-b0 (merge), then close the middle quad a1 b0 b3 a2 (split). Inserted
  // from a2 to b3 so that the ring keeps the label (procedure 1, forward direction).
  const FaceId ring_a = face_with(mesh, a[1], true);
  const FaceId ring_b = face_with(mesh, b[0], true);
  auto r = mesh.insert_edge(corner_in(mesh, a[1], ring_a), corner_in(mesh, b[0], ring_b));
  EXPECT_FALSE(r.split);
  EXPECT_VALID(mesh);
  const FaceId ring = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, a[2], ring), corner_in(mesh, b[3], ring));
  EXPECT_TRUE(r.split);
  EXPECT_VALID(mesh);

  const auto loops = boundary_loops(mesh);
  ASSERT_EQ(loops.size(), 1u);
  EXPECT_EQ(face_valence(mesh, loops[0]), 8u);  // all eight border edges
  EXPECT_EQ(vertex_set(mesh, r.face_backward), (std::set<VertexId>{a[1], b[0], b[3], a[2]}));
  const auto s = mesh_statistics(mesh);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].faces, 3u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 1);
  EXPECT_EQ(s.parts[0].genus, 0);
}

TEST(SeedFigure39, OppositeOrientationLabelsAreDetectedBeforeInsertion) {
  Dlfl mesh;
  const auto a = labelled_quad(mesh, 0.0);
  const auto b = labelled_quad(mesh, 2.0);
  // Flip b's label onto its real face: its labelled face now runs the other way round.
  const FaceId ring_b = face_with(mesh, b[0], true);
  const FaceId real_b = face_with(mesh, b[0], false);
  mesh.set_bounding(ring_b, false);
  mesh.set_bounding(real_b, true);
  const FaceId ring_a = face_with(mesh, a[1], true);

  const auto version = mesh.topology_version();
  const auto faces_before = mesh.num_faces();
  const auto corners_before = mesh.num_corners();
  EXPECT_THROW(mesh.insert_edge(corner_in(mesh, a[1], ring_a), corner_in(mesh, b[0], real_b)),
               LabelOrientationError);
  EXPECT_EQ(mesh.topology_version(), version);
  EXPECT_EQ(mesh.num_faces(), faces_before);
  EXPECT_EQ(mesh.num_corners(), corners_before);
  EXPECT_TRUE(mesh.is_bounding(ring_a));
  EXPECT_EQ(face_valence(mesh, ring_a), 4u);
  EXPECT_VALID(mesh);
}

TEST(SeedFigure40, DeletingAnEdgeBesideALabelledFacePutsTheOtherEdgesOnTheBorder) {
  Dlfl mesh;
  const auto v = build_chalice_steps(mesh, true);
  const FaceId top = boundary_loops(mesh).at(0);
  // e1: the edge v2-v4, between the labelled top and the real face v1 v4 v2.
  EdgeId e1;
  FaceId old_face;
  for (CornerId c : face_corners(mesh, top)) {
    if (mesh.vertex(c) == v[1] && mesh.vertex(mesh.next(c)) == v[3]) {
      e1 = mesh.edge(c);
      old_face = mesh.face(mesh.partner(c));
    }
  }
  ASSERT_TRUE(e1.valid());
  ASSERT_FALSE(mesh.is_bounding(old_face));
  const auto old_vertices = vertex_set(mesh, old_face);
  const auto result = mesh.delete_edge(e1);
  EXPECT_VALID(mesh);
  EXPECT_FALSE(result.split);
  EXPECT_TRUE(mesh.is_bounding(result.face_a));
  // The other two edges of the old face now each have the labelled face on one side.
  std::size_t border_edges = 0;
  for (CornerId c : face_corners(mesh, result.face_a)) {
    const auto ends = std::set<VertexId>{mesh.vertex(c), mesh.vertex(mesh.next(c))};
    if (ends == std::set<VertexId>{v[0], v[1]} || ends == std::set<VertexId>{v[0], v[3]}) {
      ++border_edges;
    }
  }
  EXPECT_TRUE(old_vertices.count(v[0]));
  EXPECT_EQ(border_edges, 2u);
  const auto s = mesh_statistics(mesh);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].faces, 2u);
  EXPECT_EQ(s.parts[0].rings, 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 1);
  EXPECT_EQ(boundary_loops(mesh).size(), 1u);
}

TEST(SeedFigures41And42, TwoTetrahedraJoinedAtOneVertexKeepEveryFaceWhole) {
  Dlfl mesh;
  const auto v = build_chalice_steps(mesh, false);  // the first tetrahedron, v1..v4
  // The base triangle v5 v6 v7 of the second tetrahedron: a polygon (two opposite faces).
  const VertexId v5 = mesh.create_vertex({0, 0, -1});
  const VertexId v6 = mesh.create_vertex({-1, 0, -1});
  const VertexId v7 = mesh.create_vertex({0, -1, -1});
  auto r = mesh.insert_edge(sphere(mesh, v5), sphere(mesh, v6));
  r = mesh.insert_edge(corner_in(mesh, v6, r.face_forward), sphere(mesh, v7));
  r = mesh.insert_edge(corner_in(mesh, v7, r.face_forward), corner_in(mesh, v5, r.face_forward));
  EXPECT_VALID(mesh);
  const FaceId f6 = r.face_forward;

  // Step 2: AddRotation(v1) creates the point sphere f7 on v1.
  const auto added = mesh.add_rotation(v[0]);
  EXPECT_EQ(rotation_count(mesh, v[0]), 2u);
  EXPECT_VALID(mesh);
  // Step 3: v1 (f7) - v5 (f6): merge.
  r = mesh.insert_edge(added.corner, corner_in(mesh, v5, f6));
  EXPECT_FALSE(r.split);
  EXPECT_FALSE(r.joined_existing);
  EXPECT_VALID(mesh);
  // Step 4: v1 (f6) - v7 (f6): split.
  const FaceId f6b = r.face_forward;
  r = mesh.insert_edge(corner_in(mesh, v[0], f6b), corner_in(mesh, v7, f6b));
  EXPECT_TRUE(r.split);
  EXPECT_VALID(mesh);
  // Step 5: v1 (f6) - v6 (f6), in the face that still holds v6.
  const FaceId f6c = vertex_set(mesh, r.face_forward).count(v6) ? r.face_forward : r.face_backward;
  r = mesh.insert_edge(corner_in(mesh, v[0], f6c), corner_in(mesh, v6, f6c));
  EXPECT_TRUE(r.split);
  EXPECT_VALID(mesh);

  // The junction vertex has two rotations; no face is degenerate; each part is a sphere.
  EXPECT_EQ(rotation_count(mesh, v[0]), 2u);
  EXPECT_EQ(non_manifold_vertices(mesh), std::vector<VertexId>{v[0]});
  const auto faces = live_faces(mesh);
  EXPECT_EQ(faces.size(), 8u);
  for (FaceId f : faces) {
    EXPECT_EQ(face_valence(mesh, f), 3u);
    EXPECT_EQ(vertex_set(mesh, f).size(), 3u) << to_string(f) << " repeats a vertex";
  }
  const auto s = mesh_statistics(mesh);
  ASSERT_EQ(s.parts.size(), 2u);
  for (const auto& p : s.parts) {
    EXPECT_EQ(p.euler_characteristic, 2);
    EXPECT_EQ(p.vertices, 4u);
  }
  // Figure 42: v1's node lists two rotations of three corners each.
  for (const auto& around : faces_around_vertex(mesh, v[0]))
    EXPECT_EQ(around.size(), 3u);

  // CleanRotations keeps both: neither is a point sphere.
  mesh.clean_rotations(v[0]);
  EXPECT_EQ(rotation_count(mesh, v[0]), 2u);
}

TEST(SeedFigure14, TwoCubesSharingAnEdgeHaveOneEdgeWithTwoCornerPairs) {
  Dlfl mesh;
  const auto a = append_oriented_manifold(mesh, cube_mesh({0, 0, 0}, 1.0));
  BuildOptions join;
  join.join_vertices.assign(8, VertexId{});
  join.join_vertices[0] = a[3];  // (1, 1, 0)
  join.join_vertices[4] = a[7];  // (1, 1, 1)
  append_oriented_manifold(mesh, cube_mesh({1, 1, 0}, 1.0), join);
  EXPECT_VALID(mesh);

  const auto nm_edges = non_manifold_edges(mesh);
  ASSERT_EQ(nm_edges.size(), 1u);
  const EdgeId shared = nm_edges[0];
  EXPECT_EQ(mesh.edge_pair_count(shared), 2u);
  const auto [p, q] = edge_vertices(mesh, shared);
  EXPECT_EQ((std::set<VertexId>{p, q}), (std::set<VertexId>{a[3], a[7]}));
  // Four distinct faces meet at the edge, two from each cube.
  const auto faces = edge_faces(mesh, shared);
  EXPECT_EQ(std::set<FaceId>(faces.begin(), faces.end()).size(), 4u);
  EXPECT_EQ(rotation_count(mesh, a[3]), 2u);
  EXPECT_EQ(rotation_count(mesh, a[7]), 2u);

  const auto s = mesh_statistics(mesh);
  EXPECT_EQ(s.vertices, 14u);
  EXPECT_EQ(s.edges, 23u);  // 24 edge pairs, two of them in one edge node
  EXPECT_EQ(s.faces, 12u);
  ASSERT_EQ(s.parts.size(), 2u);
  for (const auto& part : s.parts)
    EXPECT_EQ(part.euler_characteristic, 2);

  // Deleting one pair leaves an ordinary edge; deleting the edge removes the rest.
  mesh.delete_edge_pair(mesh.edge_pairs(shared)[1].a);
  EXPECT_VALID(mesh);
  EXPECT_EQ(mesh.edge_pair_count(shared), 1u);
  EXPECT_TRUE(non_manifold_edges(mesh).empty());
}

}  // namespace
}  // namespace bisturi
