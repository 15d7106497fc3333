// import_polygons(): procedures 3-6 and the cases the seed left open. After every import the
// DLFL validates and every kept input face appears as one face with the same vertex cycle.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/shapes.h"

namespace bisturi {
namespace {

/// validate() passes and every kept face is stored with its input cycle (reversed if flipped).
void expect_faithful(const PolygonMesh& in, const ImportResult& r) {
  const auto report = validate(r.mesh);
  EXPECT_TRUE(report.ok()) << report.summary();
  std::size_t kept = 0;
  for (std::uint32_t f = 0; f < in.face_count(); ++f) {
    const FaceId face = r.face_of_input[f];
    if (!face.valid()) continue;
    ++kept;
    ASSERT_TRUE(r.mesh.alive(face));
    EXPECT_FALSE(r.mesh.is_bounding(face)) << "input face " << f << " is labelled";
    std::vector<VertexId> expected;
    for (std::uint32_t i : in.face(f))
      expected.push_back(r.vertex_of_input[i]);
    if (r.flipped[f]) std::reverse(expected.begin(), expected.end());
    const std::vector<VertexId> stored = face_vertices(r.mesh, face);
    ASSERT_EQ(stored.size(), expected.size()) << "input face " << f;
    bool same = false;
    const std::size_t n = expected.size();
    for (std::size_t shift = 0; shift < n && !same; ++shift) {
      same = true;
      for (std::size_t j = 0; j < n && same; ++j)
        same = stored[j] == expected[(j + shift) % n];
    }
    EXPECT_TRUE(same) << "input face " << f << " changed its cycle";
  }
  EXPECT_EQ(kept, r.report.faces);
  EXPECT_EQ(kept + r.report.dropped.size(), in.face_count());
}

/// Every polygon with its own copies of its corners (a soup, as STL gives).
PolygonMesh as_soup(const PolygonMesh& m) {
  PolygonMesh soup;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    std::vector<std::uint32_t> face;
    for (std::uint32_t i : m.face(f)) {
      face.push_back(static_cast<std::uint32_t>(soup.positions.size()));
      soup.positions.push_back(m.positions[i]);
    }
    soup.add_face(face);
  }
  return soup;
}

TEST(PolygonImport, SoupWeldsIntoAClosedCube) {
  const PolygonMesh soup = as_soup(cube_mesh({0, 0, 0}, 2.0));
  const ImportResult r = import_polygons(soup, false);
  expect_faithful(soup, r);
  EXPECT_EQ(r.report.welded_vertices, 16u);
  EXPECT_EQ(r.report.vertices, 8u);
  EXPECT_EQ(r.report.edges, 12u);
  ASSERT_EQ(r.report.parts.size(), 1u);
  EXPECT_TRUE(r.report.parts[0].closed);
  EXPECT_EQ(r.report.parts[0].euler, 2);
  EXPECT_EQ(r.report.parts[0].genus, 0);
  EXPECT_EQ(r.mesh.num_vertices(), 8u);
}

TEST(PolygonImport, IndexedInputKeepsCoincidentVerticesApartUnlessAskedToWeld) {
  const PolygonMesh soup = as_soup(cube_mesh({0, 0, 0}, 1.0));
  const ImportResult apart = import_polygons(soup, true);
  expect_faithful(soup, apart);
  EXPECT_EQ(apart.report.parts.size(), 6u);  // six loose quads, like the lips of an incision
  EXPECT_EQ(apart.report.vertices, 24u);
  ImportOptions weld;
  weld.weld = true;
  const ImportResult joined = import_polygons(soup, true, weld);
  expect_faithful(soup, joined);
  EXPECT_EQ(joined.report.parts.size(), 1u);
  EXPECT_EQ(joined.report.vertices, 8u);
}

TEST(PolygonImport, ToleranceWeldsNearbyVertices) {
  PolygonMesh soup = as_soup(cube_mesh({0, 0, 0}, 1.0));
  for (std::size_t i = 0; i < soup.positions.size(); ++i) {
    soup.positions[i].x += 1e-7 * double(i % 3);
  }
  EXPECT_GT(import_polygons(soup, false).report.vertices, 8u);  // exact weld misses them
  ImportOptions options;
  options.weld_tolerance = 1e-5;
  const ImportResult r = import_polygons(soup, false, options);
  expect_faithful(soup, r);
  EXPECT_EQ(r.report.vertices, 8u);
  EXPECT_TRUE(r.report.parts.at(0).closed);
}

TEST(PolygonImport, InconsistentOrientationIsFlipped) {
  PolygonMesh m = cube_mesh({0, 0, 0}, 1.0);
  for (std::size_t f : {2u, 5u}) {
    std::reverse(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
  }
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  EXPECT_EQ(r.report.flipped_faces, 2u);
  EXPECT_TRUE(r.flipped[2] && r.flipped[5]);
  EXPECT_EQ(r.report.parts.at(0).euler, 2);
  EXPECT_TRUE(r.report.parts.at(0).closed);
}

TEST(PolygonImport, MoebiusStripIsReportedNonOrientableAndStoredAlongASeam) {
  const std::uint32_t n = 12;
  PolygonMesh m;
  for (std::uint32_t i = 0; i < n; ++i) {
    const double t = 2.0 * std::numbers::pi * double(i) / double(n);
    for (double w : {-0.3, 0.3}) {
      // The strip's width turns by half a turn over one loop.
      const double c = std::cos(t / 2.0) * w;
      m.positions.emplace_back((1.0 + c) * std::cos(t), (1.0 + c) * std::sin(t),
                               std::sin(t / 2.0) * w);
    }
  }
  for (std::uint32_t i = 0; i + 1 < n; ++i)
    m.add_face({2 * i, 2 * i + 2, 2 * i + 3, 2 * i + 1});
  m.add_face({2 * (n - 1), 1, 0, 2 * (n - 1) + 1});  // the half twist: top meets bottom
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  ASSERT_EQ(r.report.parts.size(), 1u);
  const ImportPart& part = r.report.parts[0];
  EXPECT_FALSE(part.orientable);
  EXPECT_FALSE(part.genus.has_value());
  EXPECT_EQ(part.boundary_loops, 1u);  // a Moebius strip has one edge
  EXPECT_EQ(part.euler, 0);
  EXPECT_EQ(r.report.seam_edges, 1u);
  EXPECT_EQ(r.report.faces, n);
}

TEST(PolygonImport, BowTieInsideOnePartGetsTwoRotations) {
  // A hexagonal fan around v with two triangles missing, so that v has two fans; three more
  // triangles join the fans' rims, making it one part.
  PolygonMesh m;
  m.positions.emplace_back(0, 0, 0);  // v = 0
  for (int i = 0; i < 6; ++i) {
    const double a = std::numbers::pi / 3.0 * i;
    m.positions.emplace_back(std::cos(a), std::sin(a), 0);  // r_i = 1 + i
  }
  m.positions.emplace_back(1.5, 1.5, 0.5);  // y = 7
  auto r_ = [](std::uint32_t i) { return 1 + i % 6; };
  for (std::uint32_t i : {5u, 0u, 2u, 3u})
    m.add_face({0, r_(i), r_(i + 1)});
  m.add_face({r_(1), r_(0), 7});
  m.add_face({r_(1), 7, r_(2)});
  m.add_face({r_(2), 7, r_(3)});
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  ASSERT_EQ(r.report.parts.size(), 1u);
  EXPECT_EQ(r.report.nonmanifold_vertices, 1u);
  EXPECT_EQ(r.report.nonmanifold_edges, 0u);
  EXPECT_EQ(rotation_count(r.mesh, r.vertex_of_input[0]), 2u);
  // No face of v degenerates: each of its four triangles keeps three distinct vertices.
  for (const auto& fan : faces_around_vertex(r.mesh, r.vertex_of_input[0])) {
    for (FaceId f : fan) {
      if (!r.mesh.is_bounding(f)) {
        EXPECT_EQ(face_valence(r.mesh, f), 3u);
      }
    }
  }
}

TEST(PolygonImport, FaceThatRepeatsAVertexIsKeptWhole) {
  // Two triangles of one polygon touching at vertex 0: 0 1 2 0 3 4.
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
  m.add_face({0, 1, 2, 0, 3, 4});
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  EXPECT_TRUE(r.report.dropped.empty());
  EXPECT_EQ(face_valence(r.mesh, r.face_of_input[0]), 6u);
}

TEST(PolygonImport, DegenerateFacesAreDroppedAndCounted) {
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {2, 0, 0}, {0, 0, 1}};
  m.add_face({0, 1, 2});     // kept
  m.add_face({0, 0, 1});     // two distinct vertices
  m.add_face({0, 1, 1, 2});  // consecutive repeat
  m.add_face({0, 1, 3});     // collinear: zero area
  m.add_face({1, 0, 4});     // kept
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  ASSERT_EQ(r.report.dropped.size(), 3u);
  EXPECT_EQ(r.report.dropped[0].face, 1u);
  EXPECT_EQ(r.report.dropped[0].reason, DropReason::TooFewDistinctVertices);
  EXPECT_EQ(r.report.dropped[1].face, 2u);
  EXPECT_EQ(r.report.dropped[1].reason, DropReason::RepeatedConsecutiveVertex);
  EXPECT_EQ(r.report.dropped[2].face, 3u);
  EXPECT_EQ(r.report.dropped[2].reason, DropReason::ZeroArea);
  EXPECT_EQ(r.report.faces, 2u);
  EXPECT_EQ(r.report.isolated_vertices, 1u);  // vertex 3 only served the dropped face
}

TEST(PolygonImport, DuplicateFacesAreKeptAndCounted) {
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.add_face({0, 1, 2});
  m.add_face({1, 2, 0});  // the same cycle, another start
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  EXPECT_EQ(r.report.duplicate_faces, 1u);
  EXPECT_EQ(r.report.flipped_faces, 1u);  // the pair closes into a two-faced sphere
  ASSERT_EQ(r.report.parts.size(), 1u);
  EXPECT_TRUE(r.report.parts[0].closed);
  EXPECT_EQ(r.report.parts[0].euler, 2);
}

TEST(PolygonImport, IsolatedVerticesAreCountedAndKept) {
  PolygonMesh m = tetrahedron_mesh();
  m.positions.emplace_back(5, 5, 5);
  m.positions.emplace_back(6, 6, 6);
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  EXPECT_EQ(r.report.vertices, 4u);
  EXPECT_EQ(r.report.isolated_vertices, 2u);
  EXPECT_EQ(r.mesh.num_vertices(), 6u);
  EXPECT_TRUE(
      r.mesh.is_point_sphere(r.mesh.rotation_corner(r.mesh.first_rotation(r.vertex_of_input[5]))));
}

TEST(PolygonImport, EdgeInThreeFacesBecomesOneEdgeWithThreePairs) {
  // A book of three pages on the spine 0-1.
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}};
  m.add_face({0, 1, 2});
  m.add_face({1, 0, 3});
  m.add_face({0, 1, 4});
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  EXPECT_EQ(r.report.nonmanifold_edges, 1u);
  EXPECT_EQ(r.report.nonmanifold_vertices, 2u);
  EXPECT_EQ(r.report.parts.size(), 3u);
  const auto nm = non_manifold_edges(r.mesh);
  ASSERT_EQ(nm.size(), 1u);
  EXPECT_EQ(r.mesh.edge_pair_count(nm[0]), 3u);
}

TEST(PolygonImport, TorusKeepsGenusOne) {
  const PolygonMesh m = torus_mesh(3.0, 1.0, 16, 8, false);
  const ImportResult r = import_polygons(m, true);
  expect_faithful(m, r);
  ASSERT_EQ(r.report.parts.size(), 1u);
  EXPECT_EQ(r.report.parts[0].euler, 0);
  EXPECT_EQ(r.report.parts[0].genus, 1);
}

/// A numbering-free picture of a DLFL: face cycles as vertex sequences (from the smallest),
/// labels, rotation counts, edge pair counts.
struct Shape {
  std::vector<std::pair<std::vector<std::uint32_t>, bool>> faces;
  std::vector<std::size_t> rotations_per_vertex;
  std::vector<std::size_t> pairs_per_edge;
  bool operator==(const Shape&) const = default;
};

Shape shape_of(const Dlfl& d) {
  Shape s;
  for (std::uint32_t f = 0; f < d.face_capacity(); ++f) {
    if (!d.alive(FaceId(f))) continue;
    std::vector<std::uint32_t> cycle;
    for (VertexId v : face_vertices(d, FaceId(f)))
      cycle.push_back(v.idx);
    std::rotate(cycle.begin(), std::min_element(cycle.begin(), cycle.end()), cycle.end());
    s.faces.emplace_back(cycle, d.is_bounding(FaceId(f)));
  }
  std::sort(s.faces.begin(), s.faces.end());
  for (std::uint32_t v = 0; v < d.vertex_capacity(); ++v) {
    if (d.alive(VertexId(v))) s.rotations_per_vertex.push_back(rotation_count(d, VertexId(v)));
  }
  for (std::uint32_t e = 0; e < d.edge_capacity(); ++e) {
    if (d.alive(EdgeId(e))) s.pairs_per_edge.push_back(d.edge_pair_count(EdgeId(e)));
  }
  std::sort(s.pairs_per_edge.begin(), s.pairs_per_edge.end());
  return s;
}

TEST(PolygonImport, OneLinearPassBuildsWhatTheOperatorsBuild) {
  std::vector<PolygonMesh> meshes = {cube_mesh({0, 0, 0}, 1.0), torus_mesh(3, 1, 12, 6, true),
                                     grid_mesh(4, 3, 1.0, false), tube_mesh(1, 2, 8, 3)};
  PolygonMesh book;  // an edge in three faces
  book.positions = {{0, 0, 0}, {0, 0, 1}, {1, 0, 0}, {-1, 0, 0}, {0, 1, 0}};
  book.add_face({0, 1, 2});
  book.add_face({1, 0, 3});
  book.add_face({0, 1, 4});
  meshes.push_back(book);
  const PolygonMesh tet = tetrahedron_mesh();
  PolygonMesh tetras = tet;  // two tetrahedra sharing vertex 0
  for (std::uint32_t f = 0; f < 4; ++f) {
    std::vector<std::uint32_t> face;
    for (std::uint32_t i : tet.face(f))
      face.push_back(i == 0 ? 0 : i + 3);
    tetras.add_face(face);
  }
  for (std::size_t i = 1; i < 4; ++i)
    tetras.positions.push_back(-tet.positions[i]);
  meshes.push_back(tetras);
  PolygonMesh twice = tet;  // every face twice: edges in four faces
  for (std::uint32_t f = 0; f < 4; ++f)
    twice.add_face(tet.face(f));
  meshes.push_back(twice);

  for (std::size_t i = 0; i < meshes.size(); ++i) {
    ImportOptions by_operators;
    by_operators.use_operators = true;
    const ImportResult fast = import_polygons(meshes[i], true);
    const ImportResult slow = import_polygons(meshes[i], true, by_operators);
    expect_faithful(meshes[i], fast);
    expect_faithful(meshes[i], slow);
    EXPECT_EQ(shape_of(fast.mesh), shape_of(slow.mesh)) << "mesh " << i;
    EXPECT_EQ(fast.face_of_input.size(), slow.face_of_input.size());
  }
}

TEST(PolygonImport, RefusesUninterpretableInput) {
  PolygonMesh m = tetrahedron_mesh();
  m.indices[3] = 17;
  EXPECT_THROW(import_polygons(m, true), InputError);
  PolygonMesh n = tetrahedron_mesh();
  n.positions[1].z = std::numeric_limits<double>::infinity();
  EXPECT_THROW(import_polygons(n, true), InputError);
}

}  // namespace
}  // namespace bisturi
