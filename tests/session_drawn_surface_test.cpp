// A solid drawn finer than it is simulated ([solids.drawn]) and the structures inside it
// ([[solids.inner]]): the liver scene's drawn surface riding on its volume through the scripted
// procedure: it stays as close to the simulated surface as it was at rest, the procedure's cut
// opens it too, and the wound gapes wider over the second after the cut.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cstdint>
#include <cstdio>
#include <string>
#include <vector>

#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/procedure.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session_sim.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/scene/polygon_export.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/sim/units.h"
#include "liver_procedure.h"
#include "session/drawn_surface.h"

namespace bisturi::runtime {
namespace {

using devices::Nanoseconds;

/// The vertices of `mesh`'s wound walls (its faces marked kInteriorFaces), once per face.
std::vector<VertexId> walls(const Dlfl& mesh) {
  std::vector<VertexId> out;
  if (!mesh.face_properties().has(kInteriorFaces)) return out;
  const auto& interior = mesh.face_properties().get<std::uint8_t>(kInteriorFaces);
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId id{f};
    if (!mesh.alive(id) || !interior[id]) continue;
    for (const VertexId v : face_vertices(mesh, id))
      out.push_back(v);
  }
  return out;
}

TEST(LiverScene, TheDrawnLiverRidesOnTheVolumeAndIsCutWithIt) {
  LiverProcedure liver;
  const SceneDescription& scene = liver.scene;
  ASSERT_TRUE(scene.solids[0].drawn.has_value());
  SessionSim& sim = liver.sim;
  const sim::VolumeBody* volume = sim.world().volume(0);
  ASSERT_NE(volume, nullptr);
  auto lattice = std::make_shared<const sim::HexLattice>(volume->volume().lattice());
  DrawnSurface drawn(*build_drawn_surface(scene.solids[0], "liver.toml"), &sim.world().body(0),
                     lattice);
  // The structures inside it, riding on the same volume.
  std::vector<DrawnSurface> inner;
  for (const SolidDescription& d : scene.solids[0].inner)
    inner.emplace_back(build_solid(d, "liver.toml"), nullptr, lattice);
  ASSERT_EQ(inner.size(), 2u);  // the lesion and the vein
  // Tens of thousands of vertices drawn on the few hundred simulated.
  EXPECT_GT(drawn.vertices(), 10u * sim.world().body(0).mesh().num_vertices());
  EXPECT_GT(drawn.rest_gap_mm(), 0.0);
  EXPECT_LT(drawn.rest_gap_mm(), 6.0);

  const auto simulated_mm = [&] {
    std::vector<glm::dvec3> x;
    for (const glm::dvec3& q : sim.world().body(0).positions())
      x.push_back(sim::sim_to_scene(q));
    return x;
  };
  const auto nodes = [&] {
    const auto x = volume->volume().positions();
    return std::vector<glm::dvec3>(x.begin(), x.end());
  };
  double most_gap = 0.0, most_moved = 0.0;
  const std::vector<glm::dvec3> rest(drawn.mesh().positions().begin(),
                                     drawn.mesh().positions().end());
  std::size_t cuts_seen = 0;
  std::uint64_t lattice_version = volume->lattice_version();
  for (std::int64_t k = 1; k <= liver.steps(); ++k) {
    (void)liver.step(k);
    if (k % 6 != 0 && sim.incisions().size() == cuts_seen) continue;  // ~ the display's rate
    if (volume->lattice_version() != lattice_version) {
      // The cut separated the volume: its lattice has more nodes.
      lattice_version = volume->lattice_version();
      lattice = std::make_shared<const sim::HexLattice>(volume->volume().lattice());
      drawn.use_lattice(lattice);
      for (DrawnSurface& structure : inner)
        structure.use_lattice(lattice);
    }
    drawn.follow(nodes());
    for (; cuts_seen < sim.incisions().size(); ++cuts_seen) {
      const Incision& cut = sim.incisions()[cuts_seen];
      if (cut.body != 0) continue;
      ASSERT_TRUE(drawn.cut(cut.points_m, cut.tips_m)) << "cut " << cuts_seen;
      EXPECT_TRUE(validate(drawn.mesh()).ok());
      // The drawn surface opens along the blade, its wound closed by walls down to the blade's
      // tip: every wall vertex lies near the blade's points or its tips.
      bool open = false;
      for (std::uint32_t f = 0; f < drawn.mesh().face_capacity(); ++f)
        open = open || (drawn.mesh().alive(FaceId(f)) && drawn.mesh().is_bounding(FaceId(f)));
      EXPECT_FALSE(open);
      const std::vector<VertexId> wall = walls(drawn.mesh());
      ASSERT_GE(wall.size(), 8u);
      for (const VertexId v : wall) {
        const glm::dvec3& w = drawn.mesh().positions()[v.idx];
        double nearest = 1e9;
        for (std::size_t b = 0; b < cut.points_m.size(); ++b)
          nearest = std::min({nearest, glm::length(w - sim::sim_to_scene(cut.points_m[b])),
                              glm::length(w - sim::sim_to_scene(cut.tips_m[b]))});
        EXPECT_LT(nearest, 6.0);
      }
    }
    most_gap = std::max(most_gap, drawn.gap_mm(simulated_mm()));
    for (DrawnSurface& structure : inner)
      structure.follow(nodes());
    for (std::size_t v = 0; v < rest.size(); ++v)
      most_moved = std::max(most_moved, glm::length(drawn.mesh().positions()[v] - rest[v]));
  }
  EXPECT_EQ(cuts_seen, sim.incisions().size());
  EXPECT_GE(sim.incisions().size(), 1u);
  std::printf("opening at the end %.3f mm\n", drawn.opening_mm());
  // The procedure pressed the liver millimetres deep, and the drawn surface went with it: the
  // two surfaces stayed as far apart as at rest, to a millimetre.
  EXPECT_GT(most_moved, 2.0);
  EXPECT_LT(most_gap, drawn.rest_gap_mm() + 1.0);
  // The structures stayed inside, as deep as they were: no vertex of theirs came within 8 mm
  // of the liver's outer surface (the lesion lies 15 mm in, the vein 12 mm; the wound's walls
  // go down 14 mm towards the lesion and are not counted).
  const Dlfl& liver_mesh = drawn.mesh();
  std::vector<std::uint8_t> on_wall(liver_mesh.vertex_capacity(), 0);
  for (const VertexId v : walls(liver_mesh))
    on_wall[v.idx] = 1;
  for (const DrawnSurface& structure : inner) {
    double nearest = 1e9;
    const auto& liver_x = liver_mesh.positions();
    for (std::uint32_t v = 0; v < structure.mesh().vertex_capacity(); ++v) {
      if (!structure.mesh().alive(VertexId(v))) continue;
      const glm::dvec3& p = structure.mesh().positions()[v];
      for (std::uint32_t w = 0; w < liver_mesh.vertex_capacity(); ++w)
        if (liver_mesh.alive(VertexId(w)) && !on_wall[w])
          nearest = std::min(nearest, glm::length(p - liver_x[w]));
    }
    EXPECT_GT(nearest, 8.0);
  }
}

/// The liver's drawn surface on its volume's lattice as it is now.
DrawnSurface drawn_liver(LiverProcedure& liver) {
  return DrawnSurface(
      *build_drawn_surface(liver.scene.solids[0], "liver.toml"), &liver.sim.world().body(0),
      std::make_shared<const sim::HexLattice>(liver.sim.world().volume(0)->volume().lattice()));
}

/// Moves the drawn surface with the volume's nodes as they are now.
void follow_volume(DrawnSurface& drawn, const sim::VolumeBody& volume) {
  const auto x = volume.volume().positions();
  drawn.follow(std::vector<glm::dvec3>(x.begin(), x.end()));
}

TEST(LiverScene, TheScriptedCutOpensAWoundThatWidensOverTheNextSecond) {
  LiverProcedure liver;
  SessionSim& sim = liver.sim;
  const sim::VolumeBody* volume = sim.world().volume(0);
  DrawnSurface drawn = drawn_liver(liver);
  const std::size_t nodes = volume->volume().lattice().rest.size();
  std::int64_t k = 1;
  for (; sim.incisions().empty(); ++k)
    (void)liver.step(k);
  ASSERT_GT(volume->separated_faces(), 0u);
  EXPECT_GT(volume->volume().lattice().rest.size(), nodes);  // the walls' nodes were copied
  std::printf("%zu faces separated, %zu nodes now (of %zu), %zu cells\n", volume->separated_faces(),
              volume->volume().lattice().rest.size(), nodes,
              volume->volume().lattice().cells.size());
  drawn.use_lattice(std::make_shared<const sim::HexLattice>(volume->volume().lattice()));
  ASSERT_TRUE(drawn.cut(sim.incisions().front().points_m, sim.incisions().front().tips_m));
  EXPECT_TRUE(validate(drawn.mesh()).ok());
  const auto follow = [&] { follow_volume(drawn, *volume); };
  follow();
  const double at_cut = drawn.opening_mm();
  std::vector<double> opening;  // every 50 ms for a second
  for (int s = 1; s <= 500; ++s, ++k) {
    (void)liver.step(k);
    if (s % 25 != 0) continue;
    follow();
    opening.push_back(drawn.opening_mm());
  }
  // Closed at the cut; then the lips part under the liver's tension, further every 50 ms (to
  // the solve's error) as the walls let go: a few tenths of a millimetre at first, millimetres
  // after the second.
  EXPECT_LT(at_cut, 0.05);
  for (std::size_t i = 1; i < opening.size(); ++i)
    EXPECT_GT(opening[i], opening[i - 1] - 0.02) << "at " << 50 * (i + 1) << " ms";
  EXPECT_LT(opening[1], 0.5 * opening.back());
  EXPECT_GT(opening.back(), 2.0);
  std::printf("the drawn wound opened %.2f mm at 0.1 s, %.2f at 0.5 s, %.2f at 1 s\n", opening[1],
              opening[9], opening.back());
}

TEST(LiverScene, ASecondCutOnTheUpperSurfaceOpensAndTheFirstWoundStaysOpen) {
  // After the scripted cut, a second 30 mm across the liver's upper surface, 6 mm deep, far
  // from the first: it splits and parts the coarse cells along it (the lattice built again, the
  // first wound separated again), both surfaces stay closed and valid, the steps run clean, the
  // second wound opens, and the drawn first wound goes on opening as it did.
  LiverProcedure liver;
  SessionSim& sim = liver.sim;
  const sim::VolumeBody* volume = sim.world().volume(0);
  DrawnSurface drawn = drawn_liver(liver);
  const auto follow = [&] { follow_volume(drawn, *volume); };
  std::int64_t k = 1;
  for (; sim.incisions().empty(); ++k)
    (void)liver.step(k);
  drawn.use_lattice(std::make_shared<const sim::HexLattice>(volume->volume().lattice()));
  ASSERT_TRUE(drawn.cut(sim.incisions().front().points_m, sim.incisions().front().tips_m));
  for (int s = 0; s < 250; ++s, ++k)
    (void)liver.step(k);
  follow();
  const double first_before = drawn.opening_mm();
  ASSERT_GT(first_before, 0.5);

  // The second blade: surface points along x through the palpation target, the tips 6 mm in.
  const sim::SoftBody& body = sim.world().body(0);
  std::vector<glm::dvec3> entry, tip;
  for (int i = -15; i <= 15; i += 2) {
    const glm::dvec3 near = sim::scene_to_sim(glm::dvec3(135.3 + i, 78.8, 179.1));
    const sim::SurfacePoint q = sim.world().bvh(0).closest_point(body, near, 0.02);
    ASSERT_TRUE(q.found);
    entry.push_back(q.point_m);
    tip.push_back(q.point_m - 0.006 * q.normal);
  }
  const std::size_t parted_before = volume->separated_faces();
  const sim::CutResult second = sim.world().cut(0, entry, {}, tip);
  ASSERT_FALSE(second.new_vertices.empty());
  EXPECT_GT(volume->separated_faces(), parted_before);
  EXPECT_TRUE(validate(body.mesh()).ok());
  EXPECT_TRUE(body.closed());
  EXPECT_EQ(volume->embedded_vertices(), body.mesh().num_vertices());
  drawn.use_lattice(std::make_shared<const sim::HexLattice>(volume->volume().lattice()));
  ASSERT_TRUE(drawn.cut(entry, tip));
  EXPECT_TRUE(validate(drawn.mesh()).ok());
  follow();
  const double first_after = drawn.opening_mm();  // the first wound is still the widest
  EXPECT_NEAR(first_after, first_before, 0.05 * first_before);
  (void)sim.world().take_events();
  for (int s = 0; s < 500; ++s, ++k)
    (void)liver.step(k);
  EXPECT_TRUE(sim.world().take_events().empty());
  follow();
  double second_open = 0.0;
  for (std::size_t i = 0; i < second.new_vertices.size(); ++i)
    second_open = std::max(second_open, glm::length(body.position(second.new_vertices[i]) -
                                                    body.position(second.path[i + 1])));
  EXPECT_GT(second_open, 2e-4);
  EXPECT_GT(drawn.opening_mm(), first_before);  // the first wound went on opening
  std::printf(
      "second cut: %zu faces parted, opened %.2f mm in 1 s; the drawn first wound %.2f mm "
      "before it, %.2f mm just after, %.2f mm 1 s later\n",
      volume->separated_faces() - parted_before, second_open * 1e3, first_before, first_after,
      drawn.opening_mm());
}

TEST(DrawnSurface, ItFollowsAnAffineMotionExactlyAndAgainOnANewLattice) {
  // Trilinear weights carry an affine motion of the nodes exactly, for the vertices inside the
  // cells and for those a fraction of a cell outside them (extrapolated) alike; a lattice handed
  // over anew (as after the refined box moved) embeds every vertex again.
  LiverProcedure liver;
  const sim::VolumeBody* volume = liver.sim.world().volume(0);
  ASSERT_NE(volume, nullptr);
  auto lattice = std::make_shared<const sim::HexLattice>(volume->volume().lattice());
  DrawnSurface drawn(*build_drawn_surface(liver.scene.solids[0], "liver.toml"),
                     &liver.sim.world().body(0), lattice);
  const std::vector<glm::dvec3> rest(drawn.mesh().positions().begin(),
                                     drawn.mesh().positions().end());
  const glm::dmat3 a(1.02, 0.01, 0.0, -0.015, 0.99, 0.02, 0.0, 0.01, 1.01);
  const glm::dvec3 shift(0.003, -0.002, 0.001);  // metres
  const auto moved = [&](const sim::HexLattice& l) {
    std::vector<glm::dvec3> nodes;
    for (const glm::dvec3& x : l.rest)
      nodes.push_back(a * x + shift);
    return nodes;
  };
  const auto largest_error = [&] {
    double most = 0.0;
    for (std::uint32_t v = 0; v < drawn.mesh().vertex_capacity(); ++v) {
      if (!drawn.mesh().alive(VertexId(v))) continue;
      const glm::dvec3 want = sim::sim_to_scene(a * sim::scene_to_sim(rest[v]) + shift);
      most = std::max(most, glm::length(drawn.mesh().positions()[v] - want));
    }
    return most;
  };
  drawn.follow(moved(*lattice));
  EXPECT_LT(largest_error(), 1e-6);
  auto again = std::make_shared<const sim::HexLattice>(*lattice);
  drawn.use_lattice(again);
  drawn.follow(moved(*again));
  EXPECT_LT(largest_error(), 1e-6);
  // Nodes of another lattice (another count) leave the surface where it was.
  drawn.follow(std::vector<glm::dvec3>(3, glm::dvec3(0.0)));
  EXPECT_LT(largest_error(), 1e-6);
}

}  // namespace
}  // namespace bisturi::runtime
