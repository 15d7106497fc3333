// The operator-based builder of oriented manifolds: known topologies come out exactly, and
// inputs it cannot hold are refused with the element named and the mesh left unchanged.

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"

namespace bisturi {
namespace {

MeshStatistics built_stats(const PolygonMesh& m) {
  const Dlfl d = build_oriented_manifold(m);
  const auto report = validate(d);
  EXPECT_TRUE(report.ok()) << report.summary();
  return mesh_statistics(d);
}

TEST(OrientedBuilder, CubeIsAClosedGenusZeroSolid) {
  const auto s = built_stats(cube_mesh({0, 0, 0}, 1.0));
  EXPECT_EQ(s.vertices, 8u);
  EXPECT_EQ(s.edges, 12u);
  EXPECT_EQ(s.faces, 6u);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 2);
  EXPECT_EQ(s.parts[0].genus, 0);
}

TEST(OrientedBuilder, TorusHasGenusOne) {
  const auto s = built_stats(torus_mesh(3.0, 1.0, 24, 12, true));
  EXPECT_EQ(s.faces, 24u * 12u * 2u);
  EXPECT_EQ(s.edges, 24u * 12u * 3u);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 0);
  EXPECT_EQ(s.parts[0].genus, 1);
}

TEST(OrientedBuilder, GridIsADiscWithOneRing) {
  const auto s = built_stats(grid_mesh(7, 5, 1.0, false));
  EXPECT_EQ(s.bounding_faces, 1u);
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].faces, 35u);
  EXPECT_EQ(s.parts[0].rings, 1u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 1);
  EXPECT_EQ(s.parts[0].genus, 0);
}

TEST(OrientedBuilder, TubeHasTwoRings) {
  const auto s = built_stats(tube_mesh(1.0, 2.0, 16, 4));
  ASSERT_EQ(s.parts.size(), 1u);
  EXPECT_EQ(s.parts[0].rings, 2u);
  EXPECT_EQ(s.parts[0].euler_characteristic, 0);
  EXPECT_EQ(s.parts[0].genus, 0);
}

TEST(OrientedBuilder, FacesKeepTheirVertexOrder) {
  const PolygonMesh m = cube_mesh({0, 0, 0}, 1.0);
  const Dlfl d = build_oriented_manifold(m);
  // Every input face appears as a DLFL face with the same cyclic vertex order.
  std::size_t matched = 0;
  for (std::uint32_t fi = 0; fi < d.face_capacity(); ++fi) {
    if (!d.alive(FaceId(fi))) continue;
    const auto verts = face_vertices(d, FaceId(fi));
    for (std::size_t k = 0; k < m.face_count(); ++k) {
      const auto in = m.face(k);
      if (in.size() != verts.size()) continue;
      for (std::size_t shift = 0; shift < in.size(); ++shift) {
        bool same = true;
        for (std::size_t j = 0; j < in.size(); ++j) {
          same = same && verts[j].idx == in[(j + shift) % in.size()];
        }
        if (same) ++matched;
      }
    }
  }
  EXPECT_EQ(matched, 6u);
}

TEST(OrientedBuilder, RefusesInconsistentOrientation) {
  PolygonMesh m = cube_mesh({0, 0, 0}, 1.0);
  std::reverse(m.indices.begin() + m.offsets[2], m.indices.begin() + m.offsets[3]);
  Dlfl d;
  d.create_vertex();
  const auto before = d.topology_version();
  try {
    append_oriented_manifold(d, m);
    FAIL() << "accepted a flipped face";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("face"), std::string::npos) << e.what();
  }
  EXPECT_EQ(d.topology_version(), before);
  EXPECT_EQ(d.num_vertices(), 1u);
}

TEST(OrientedBuilder, RefusesBadIndicesAndCoordinates) {
  PolygonMesh m = tetrahedron_mesh();
  m.indices[4] = 9;
  EXPECT_THROW(build_oriented_manifold(m), InputError);
  PolygonMesh n = tetrahedron_mesh();
  n.positions[2].y = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(build_oriented_manifold(n), InputError);
}

TEST(OrientedBuilder, RefusesBowTieVertex) {
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {-1, 0, 0}, {-1, -1, 0}};
  m.add_face({0, 1, 2});
  m.add_face({0, 3, 4});
  try {
    build_oriented_manifold(m);
    FAIL() << "accepted a bow-tie";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("vertex 0"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bisturi
