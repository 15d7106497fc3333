// import_polygons() writes consistently oriented manifold input, closed or with boundary, straight
// into the DLFL (construction/manifold_writer.h) and builds everything else along the
// general path. The fast path must give exactly what the general path gives: every record array,
// label, rotation link and free list, the topology version, the report and the input maps. Random
// closed and open meshes (relabelled, reordered, turned, as soups, with unused vertices, dropped
// faces, several parts and duplicate faces) must take it; random damage (a flip, a bow-tie, a
// third face on an edge, every face twice) must make it give up, and the result is then the
// general path's.

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <numeric>
#include <random>
#include <string>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/shapes.h"
#include "construction/import_paths.h"

namespace bisturi {
namespace {

using construction::import_polygons_via;
using construction::ImportPath;

template <class A, class B>
bool same_bytes(const A& a, const B& b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    if (std::memcmp(&a[i], &b[i], sizeof(a[i])) != 0) return false;
  }
  return true;
}

void expect_same_dlfl(const Dlfl& a, const Dlfl& b, const std::string& what) {
  EXPECT_TRUE(same_bytes(a.corner_records(), b.corner_records())) << what << ": corners";
  EXPECT_TRUE(same_bytes(a.face_records(), b.face_records())) << what << ": faces";
  EXPECT_TRUE(same_bytes(a.edge_records(), b.edge_records())) << what << ": edges";
  EXPECT_TRUE(same_bytes(a.vertex_records(), b.vertex_records())) << what << ": vertices";
  EXPECT_TRUE(same_bytes(a.rotation_records(), b.rotation_records())) << what << ": rotations";
  EXPECT_TRUE(same_bytes(a.positions(), b.positions())) << what << ": positions";
  EXPECT_TRUE(same_bytes(a.bounding_labels(), b.bounding_labels())) << what << ": labels";
  EXPECT_EQ(a.extra_pair_lists().size(), b.extra_pair_lists().size()) << what;
  EXPECT_EQ(a.rotation_links(), b.rotation_links()) << what;
  EXPECT_EQ(a.free_list(VertexTag{}), b.free_list(VertexTag{})) << what;
  EXPECT_EQ(a.free_list(CornerTag{}), b.free_list(CornerTag{})) << what;
  EXPECT_EQ(a.free_list(FaceTag{}), b.free_list(FaceTag{})) << what;
  EXPECT_EQ(a.free_list(EdgeTag{}), b.free_list(EdgeTag{})) << what;
  EXPECT_EQ(a.free_list(RotationTag{}), b.free_list(RotationTag{})) << what;
  EXPECT_EQ(a.topology_version(), b.topology_version()) << what;
  EXPECT_EQ(a.num_vertices(), b.num_vertices()) << what;
  EXPECT_EQ(a.num_faces(), b.num_faces()) << what;
  EXPECT_EQ(a.num_edges(), b.num_edges()) << what;
}

void expect_same_report(const ImportReport& a, const ImportReport& b, const std::string& what) {
  EXPECT_EQ(a.input_vertices, b.input_vertices) << what;
  EXPECT_EQ(a.input_faces, b.input_faces) << what;
  EXPECT_EQ(a.welded_vertices, b.welded_vertices) << what;
  EXPECT_EQ(a.vertices, b.vertices) << what;
  EXPECT_EQ(a.isolated_vertices, b.isolated_vertices) << what;
  EXPECT_EQ(a.edges, b.edges) << what;
  EXPECT_EQ(a.faces, b.faces) << what;
  ASSERT_EQ(a.dropped.size(), b.dropped.size()) << what;
  for (std::size_t i = 0; i < a.dropped.size(); ++i) {
    EXPECT_EQ(a.dropped[i].face, b.dropped[i].face) << what;
    EXPECT_EQ(a.dropped[i].reason, b.dropped[i].reason) << what;
  }
  EXPECT_EQ(a.nonmanifold_edges, b.nonmanifold_edges) << what;
  EXPECT_EQ(a.nonmanifold_vertices, b.nonmanifold_vertices) << what;
  EXPECT_EQ(a.flipped_faces, b.flipped_faces) << what;
  EXPECT_EQ(a.duplicate_faces, b.duplicate_faces) << what;
  EXPECT_EQ(a.seam_edges, b.seam_edges) << what;
  ASSERT_EQ(a.parts.size(), b.parts.size()) << what;
  for (std::size_t i = 0; i < a.parts.size(); ++i) {
    const ImportPart& p = a.parts[i];
    const ImportPart& q = b.parts[i];
    EXPECT_EQ(p.faces, q.faces) << what << " part " << i;
    EXPECT_EQ(p.vertices, q.vertices) << what << " part " << i;
    EXPECT_EQ(p.edges, q.edges) << what << " part " << i;
    EXPECT_EQ(p.closed, q.closed) << what << " part " << i;
    EXPECT_EQ(p.boundary_loops, q.boundary_loops) << what << " part " << i;
    EXPECT_EQ(p.orientable, q.orientable) << what << " part " << i;
    EXPECT_EQ(p.euler, q.euler) << what << " part " << i;
    EXPECT_EQ(p.genus, q.genus) << what << " part " << i;
  }
}

/// Imports along both paths and compares; returns whether the fast path took the input.
bool compare_paths(const PolygonMesh& m, bool has_vertex_list, const ImportOptions& options,
                   const std::string& what) {
  const auto general = import_polygons_via(m, has_vertex_list, options, ImportPath::kGeneral);
  const auto fast = import_polygons_via(m, has_vertex_list, options, ImportPath::kFast);
  const ImportResult automatic = import_polygons(m, has_vertex_list, options);
  EXPECT_TRUE(general.has_value()) << what;
  if (!general) return false;
  EXPECT_TRUE(validate(general->mesh).ok()) << what;
  const ImportResult& chosen = fast ? *fast : automatic;
  expect_same_dlfl(chosen.mesh, general->mesh, what);
  expect_same_report(chosen.report, general->report, what);
  EXPECT_EQ(chosen.vertex_of_input, general->vertex_of_input) << what;
  EXPECT_EQ(chosen.face_of_input, general->face_of_input) << what;
  EXPECT_EQ(chosen.flipped, general->flipped) << what;
  if (fast) {
    expect_same_dlfl(automatic.mesh, general->mesh, what + " (auto)");
    expect_same_report(automatic.report, general->report, what + " (auto)");
  }
  return fast.has_value();
}

PolygonMesh triangulated(const PolygonMesh& m) {
  PolygonMesh out;
  out.positions = m.positions;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const auto face = m.face(f);
    for (std::size_t i = 1; i + 1 < face.size(); ++i)
      out.add_face({face[0], face[i], face[i + 1]});
  }
  return out;
}

/// A random closed, consistently oriented mesh: one to three tori, cubes or tetrahedra.
PolygonMesh random_closed(std::mt19937& rng) {
  PolygonMesh m;
  const int parts = std::uniform_int_distribution<int>(1, 3)(rng);
  for (int p = 0; p < parts; ++p) {
    PolygonMesh part;
    switch (std::uniform_int_distribution<int>(0, 3)(rng)) {
      case 0:
        part = torus_mesh(4.0, 1.0, std::uniform_int_distribution<std::size_t>(3, 9)(rng),
                          std::uniform_int_distribution<std::size_t>(3, 9)(rng), true);
        break;
      case 1:
        part = torus_mesh(4.0, 1.0, std::uniform_int_distribution<std::size_t>(3, 9)(rng),
                          std::uniform_int_distribution<std::size_t>(3, 9)(rng), false);
        break;
      case 2:
        part = cube_mesh({0, 0, 0}, 1.0);
        if (rng() % 2 != 0) part = triangulated(part);
        break;
      default:
        part = tetrahedron_mesh();
        break;
    }
    const auto base = static_cast<std::uint32_t>(m.positions.size());
    const Dlfl::Vec3 shift(10.0 * p, 0.0, 0.0);
    for (const auto& q : part.positions)
      m.positions.push_back(q + shift);
    for (std::size_t f = 0; f < part.face_count(); ++f) {
      std::vector<std::uint32_t> face;
      for (std::uint32_t i : part.face(f))
        face.push_back(base + i);
      m.add_face(face);
    }
  }
  return m;
}

/// The same surface with vertices relabelled, faces reordered and each face started elsewhere.
PolygonMesh shuffled(const PolygonMesh& m, std::mt19937& rng) {
  std::vector<std::uint32_t> label(m.positions.size());
  std::iota(label.begin(), label.end(), 0u);
  std::shuffle(label.begin(), label.end(), rng);
  PolygonMesh out;
  out.positions.resize(m.positions.size());
  for (std::size_t v = 0; v < m.positions.size(); ++v)
    out.positions[label[v]] = m.positions[v];
  std::vector<std::size_t> order(m.face_count());
  std::iota(order.begin(), order.end(), std::size_t{0});
  std::shuffle(order.begin(), order.end(), rng);
  for (std::size_t f : order) {
    const auto face = m.face(f);
    std::vector<std::uint32_t> turned;
    const std::size_t s = rng() % face.size();
    for (std::size_t i = 0; i < face.size(); ++i)
      turned.push_back(label[face[(s + i) % face.size()]]);
    out.add_face(turned);
  }
  return out;
}

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

/// Unused vertices, a degenerate face (dropped) and a closed pillow of two faces (duplicates).
PolygonMesh with_extras(const PolygonMesh& m, std::mt19937& rng) {
  PolygonMesh out = m;
  const int extras = std::uniform_int_distribution<int>(1, 3)(rng);
  for (int i = 0; i < extras; ++i)
    out.positions.push_back(Dlfl::Vec3(-5.0 - i, 1.0, 2.0));
  if (rng() % 2 != 0) {
    const std::uint32_t a = out.indices[0];
    const std::uint32_t b = out.indices[1];
    out.add_face({a, a, b});
  }
  if (rng() % 2 != 0) {
    const auto base = static_cast<std::uint32_t>(out.positions.size());
    out.positions.push_back(Dlfl::Vec3(0.0, 20.0, 0.0));
    out.positions.push_back(Dlfl::Vec3(1.0, 20.0, 0.0));
    out.positions.push_back(Dlfl::Vec3(0.0, 21.0, 0.0));
    out.add_face({base, base + 1, base + 2});
    out.add_face({base + 2, base + 1, base});
  }
  return out;
}

/// The mesh without the faces `drop` marks.
PolygonMesh without(const PolygonMesh& m, const std::vector<char>& drop) {
  PolygonMesh out;
  out.positions = m.positions;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    if (!drop[f]) out.add_face(m.face(f));
  }
  return out;
}

/// Holes that keep a manifold: faces removed that share no vertex with each other, so every
/// vertex keeps one fan (a path of faces where a face went).
PolygonMesh with_holes(const PolygonMesh& m, std::mt19937& rng) {
  std::vector<char> used(m.positions.size(), 0), drop(m.face_count(), 0);
  const int tries = std::uniform_int_distribution<int>(1, 12)(rng);
  for (int t = 0; t < tries; ++t) {
    const auto f = static_cast<std::size_t>(rng() % m.face_count());
    const auto face = m.face(f);
    if (std::any_of(face.begin(), face.end(), [&](std::uint32_t v) { return used[v] != 0; })) {
      continue;
    }
    for (std::uint32_t v : face)
      used[v] = 1;
    drop[f] = 1;
  }
  return without(m, drop);
}

/// A random open, consistently oriented manifold: a closed mesh with holes, a grid or a tube.
PolygonMesh random_open(std::mt19937& rng) {
  switch (std::uniform_int_distribution<int>(0, 2)(rng)) {
    case 0:
      return with_holes(random_closed(rng), rng);
    case 1:
      return grid_mesh(std::uniform_int_distribution<std::size_t>(1, 9)(rng),
                       std::uniform_int_distribution<std::size_t>(1, 9)(rng), 1.0, rng() % 2 != 0);
    default:
      return with_holes(tube_mesh(1.0, 3.0, std::uniform_int_distribution<std::size_t>(3, 9)(rng),
                                  std::uniform_int_distribution<std::size_t>(1, 6)(rng)),
                        rng);
  }
}

/// `trials` meshes from make(rng) (shuffled on odd trials, with extras on every third), each
/// compared across both paths indexed, as a soup and welded; returns how many the fast path took.
template <class Make>
int compare_variants(std::mt19937& rng, int trials, const std::string& label, Make make) {
  int taken = 0;
  for (int trial = 0; trial < trials; ++trial) {
    PolygonMesh m = make(rng);
    if (trial % 2 == 1) m = shuffled(m, rng);
    if (trial % 3 == 2) m = with_extras(m, rng);
    const std::string what = label + " " + std::to_string(trial);
    taken += compare_paths(m, true, {}, what + " indexed") ? 1 : 0;
    taken += compare_paths(as_soup(m), false, {}, what + " soup") ? 1 : 0;
    ImportOptions weld;
    weld.weld = true;
    taken += compare_paths(m, true, weld, what + " welded") ? 1 : 0;
  }
  return taken;
}

TEST(PolygonImportFastPath, ClosedMeshesTakeItAndMatchTheGeneralPath) {
  std::mt19937 rng(20261123);
  EXPECT_EQ(compare_variants(rng, 60, "trial", random_closed), 180);
}

TEST(PolygonImportFastPath, DamagedMeshesFallBackToTheGeneralPath) {
  std::mt19937 rng(7);
  for (int trial = 0; trial < 75; ++trial) {
    PolygonMesh m = shuffled(random_closed(rng), rng);
    const std::string what = "trial " + std::to_string(trial);
    const auto f = static_cast<std::size_t>(rng() % m.face_count());
    switch (trial % 5) {
      case 0:  // one face flipped
        std::reverse(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
        break;
      case 1: {  // one face removed, the neighbour of one of its sides flipped
        const std::uint32_t a = m.indices[m.offsets[f]];
        const std::uint32_t b = m.indices[m.offsets[f] + 1];
        PolygonMesh holed;
        holed.positions = m.positions;
        for (std::size_t g = 0; g < m.face_count(); ++g) {
          if (g != f) holed.add_face(m.face(g));
        }
        m = holed;
        for (std::size_t g = 0; g < m.face_count(); ++g) {
          const auto face = m.face(g);
          if (std::find(face.begin(), face.end(), a) != face.end() &&
              std::find(face.begin(), face.end(), b) != face.end()) {
            std::reverse(m.indices.begin() + m.offsets[g], m.indices.begin() + m.offsets[g + 1]);
            break;
          }
        }
        break;
      }
      case 2: {  // a tetrahedron on one vertex: a bow-tie
        const std::uint32_t apex = m.indices[m.offsets[f]];
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const Dlfl::Vec3 p = m.positions[apex];
        m.positions.push_back(p + Dlfl::Vec3(0.0, 0.0, 3.0));
        m.positions.push_back(p + Dlfl::Vec3(1.0, 0.0, 3.0));
        m.positions.push_back(p + Dlfl::Vec3(0.0, 1.0, 3.0));
        m.add_face({apex, base + 1, base});
        m.add_face({apex, base + 2, base + 1});
        m.add_face({apex, base, base + 2});
        m.add_face({base, base + 1, base + 2});
        break;
      }
      case 4: {  // every face twice: each edge run twice each way
        const std::size_t faces = m.face_count();
        for (std::size_t g = 0; g < faces; ++g) {
          const auto face = m.face(g);
          const std::vector<std::uint32_t> copy(face.begin(), face.end());
          m.add_face(copy);
        }
        break;
      }
      default: {  // a third face on an edge
        const auto face = m.face(f);
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        // Off the edge's line, so the new face has an area and is kept.
        m.positions.push_back(0.5 * (m.positions[face[0]] + m.positions[face[1]]) +
                              Dlfl::Vec3(0.37, -0.61, 2.3));
        m.add_face({face[0], face[1], base});
        break;
      }
    }
    EXPECT_FALSE(compare_paths(m, true, {}, what)) << what << ": the fast path took it";
    compare_paths(as_soup(m), false, {}, what + " soup");
  }
}

TEST(PolygonImportFastPath, OpenMeshesTakeItAndMatchTheGeneralPath) {
  std::mt19937 rng(4242);
  EXPECT_EQ(compare_variants(rng, 90, "open trial", random_open), 270);
}

TEST(PolygonImportFastPath, RandomlyHoledMeshesMatchTheGeneralPath) {
  // Any faces removed: bow-ties where a fan loses two faces apart, manifold holes elsewhere.
  std::mt19937 rng(99);
  int taken = 0;
  for (int trial = 0; trial < 120; ++trial) {
    const PolygonMesh closed = shuffled(random_closed(rng), rng);
    std::vector<char> drop(closed.face_count(), 0);
    const double share = std::uniform_real_distribution<double>(0.02, 0.5)(rng);
    for (auto& d : drop)
      d = std::bernoulli_distribution(share)(rng) ? 1 : 0;
    const PolygonMesh m = without(closed, drop);
    if (m.face_count() == 0) continue;
    taken += compare_paths(m, true, {}, "holed trial " + std::to_string(trial)) ? 1 : 0;
  }
  EXPECT_GT(taken, 10);
  EXPECT_LT(taken, 110);
}

TEST(PolygonImportFastPath, DamagedOpenMeshesFallBackToTheGeneralPath) {
  std::mt19937 rng(31);
  for (int trial = 0; trial < 60; ++trial) {
    PolygonMesh m = shuffled(
        grid_mesh(std::uniform_int_distribution<std::size_t>(2, 8)(rng),
                  std::uniform_int_distribution<std::size_t>(2, 8)(rng), 1.0, rng() % 2 != 0),
        rng);
    const std::string what = "open trial " + std::to_string(trial);
    const auto f = static_cast<std::size_t>(rng() % m.face_count());
    switch (trial % 4) {
      case 0:  // one face flipped
        std::reverse(m.indices.begin() + m.offsets[f], m.indices.begin() + m.offsets[f + 1]);
        break;
      case 1: {  // a second grid on one corner vertex: a bow-tie of two boundary fans
        const std::uint32_t apex = m.indices[m.offsets[f]];
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        const Dlfl::Vec3 p = m.positions[apex];
        m.positions.push_back(p + Dlfl::Vec3(0.0, 0.0, 3.0));
        m.positions.push_back(p + Dlfl::Vec3(1.0, 0.0, 3.0));
        m.add_face({apex, base, base + 1});
        break;
      }
      case 2: {  // a third face on an edge
        const auto face = m.face(f);
        const auto base = static_cast<std::uint32_t>(m.positions.size());
        m.positions.push_back(0.5 * (m.positions[face[0]] + m.positions[face[1]]) +
                              Dlfl::Vec3(0.37, -0.61, 2.3));
        m.add_face({face[0], face[1], base});
        break;
      }
      default: {  // a boundary side run twice the same way (a face copied, turned)
        const auto face = m.face(f);
        std::vector<std::uint32_t> copy(face.begin(), face.end());
        std::rotate(copy.begin(), copy.begin() + 1, copy.end());
        m.add_face(copy);
        break;
      }
    }
    EXPECT_FALSE(compare_paths(m, true, {}, what)) << what << ": the fast path took it";
    compare_paths(as_soup(m), false, {}, what + " soup");
  }
}

}  // namespace
}  // namespace bisturi
