// The blood's liquid surface (runtime/render/liquid_surface.h): a lone particle is a bead of the
// kernel's iso radius, drops apart stay apart, a pool is one closed sheet, and every part is a
// closed, outward-facing surface.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <vector>

#include "bisturi/runtime/render/liquid_surface.h"
#include "bisturi/scene/dlfl_queries.h"
#include "bisturi/scene/dlfl_validate.h"
#include "session/liquid_worker.h"

namespace bisturi::render {
namespace {

/// The volume a closed surface encloses (divergence theorem over its triangulated faces).
double enclosed_volume(const Dlfl& mesh) {
  double six_v = 0.0;
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId id{f};
    if (!mesh.alive(id) || mesh.is_bounding(id)) continue;
    const CornerId first = mesh.first_corner(id);
    const glm::dvec3 a = mesh.position(mesh.vertex(first));
    for (CornerId c = mesh.next(first); mesh.next(c) != first; c = mesh.next(c))
      six_v += glm::dot(
          a, glm::cross(mesh.position(mesh.vertex(c)), mesh.position(mesh.vertex(mesh.next(c)))));
  }
  return six_v / 6.0;
}

/// Every part closed (no ring) and of genus 0.
void expect_closed_balls(const Dlfl& mesh) {
  EXPECT_TRUE(validate(mesh).ok());
  for (const Part& part : connected_parts(mesh)) {
    const PartTopology t = part_topology(mesh, part);
    EXPECT_EQ(t.rings, 0u);
    EXPECT_EQ(t.genus, 0);
  }
}

TEST(LiquidSurface, ALoneParticleIsABeadOfTheKernelsIsoRadius) {
  LiquidSurface liquid;
  const glm::dvec3 centre{10.3, -4.1, 7.7};
  const Dlfl& bead = liquid.update(std::vector<glm::dvec3>{centre});
  expect_closed_balls(bead);
  ASSERT_EQ(connected_parts(bead).size(), 1u);
  // (1 - r^2/R^2)^3 = iso at r = R sqrt(1 - iso^(1/3)): 1.32 mm with the defaults.
  const LiquidSurfaceOptions o;
  const double radius = o.kernel_radius_mm * std::sqrt(1.0 - std::cbrt(o.iso));
  for (std::uint32_t v = 0; v < bead.vertex_capacity(); ++v) {
    if (!bead.alive(VertexId(v))) continue;
    EXPECT_NEAR(glm::length(bead.position(VertexId(v)) - centre), radius, 0.25 * o.cell_mm);
  }
  // Facing out: it encloses a positive volume, less than the sphere it is inscribed in (two
  // cells across, it is a coarse polyhedron: an inscribed octahedron holds 0.32 of the sphere).
  const double sphere = 4.0 / 3.0 * 3.14159265358979 * radius * radius * radius;
  EXPECT_GT(enclosed_volume(bead), 0.3 * sphere);
  EXPECT_LT(enclosed_volume(bead), sphere);
}

TEST(LiquidSurface, DropsApartStayApartAndAPoolIsOneSheet) {
  LiquidSurface liquid;
  // Two drops 20 mm apart: two beads, each on its own small grid.
  const Dlfl& drops = liquid.update(std::vector<glm::dvec3>{{0, 0, 0}, {20, 0, 0}});
  expect_closed_balls(drops);
  EXPECT_EQ(connected_parts(drops).size(), 2u);
  EXPECT_EQ(liquid.groups(), 2u);

  // A pool: 12 x 12 particles at the blood's rest spacing (2.4 mm) on a tray, one drop above.
  std::vector<glm::dvec3> pool;
  for (int i = 0; i < 12; ++i)
    for (int j = 0; j < 12; ++j)
      pool.push_back({2.4 * i, 2.4 * j, 0.0});
  pool.push_back({13.0, 13.0, 30.0});
  const Dlfl& sheet = liquid.update(pool);
  expect_closed_balls(sheet);
  EXPECT_EQ(connected_parts(sheet).size(), 2u);  // the pool and the drop
  // The pool's top is flat over its middle: no bead per particle there.
  double lowest_top = 1e9, highest_top = -1e9;
  for (std::uint32_t v = 0; v < sheet.vertex_capacity(); ++v) {
    if (!sheet.alive(VertexId(v))) continue;
    const glm::dvec3 p = sheet.position(VertexId(v));
    if (p.z < 0.5 || p.z > 10.0 || p.x < 6.0 || p.x > 20.0 || p.y < 6.0 || p.y > 20.0) continue;
    lowest_top = std::min(lowest_top, p.z);
    highest_top = std::max(highest_top, p.z);
  }
  ASSERT_LT(lowest_top, highest_top);
  EXPECT_LT(highest_top - lowest_top, 0.35);
  // No particles: nothing drawn.
  EXPECT_EQ(liquid.update(std::vector<glm::dvec3>{}).num_faces(), 0u);
}

TEST(LiquidSurface, ItsGroupsAreThoseOfEveryPairOfOverlappingKernels) {
  // Drops scattered in clumps and chains whose links cross cubes diagonally and two cubes on:
  // the groups are the connected parts of "closer than twice the kernel's reach", as a test of
  // every pair finds them.
  const LiquidSurfaceOptions options;
  const double link = 2.0 * options.kernel_radius_mm;
  std::uint64_t seed = 12345;
  const auto uniform = [&seed] {
    seed = seed * 6364136223846793005ULL + 1442695040888963407ULL;
    return static_cast<double>(seed >> 11) / static_cast<double>(1ULL << 53);
  };
  for (int trial = 0; trial < 4; ++trial) {
    std::vector<glm::dvec3> drops;
    for (int clump = 0; clump < 12; ++clump) {
      const glm::dvec3 centre(200.0 * uniform(), 200.0 * uniform(), 60.0 * uniform());
      const glm::dvec3 step =
          (0.6 + 0.4 * uniform()) * link *
          glm::normalize(glm::dvec3(uniform() - 0.5, uniform() - 0.5, uniform() - 0.5));
      for (int k = 0; k < 15; ++k)  // a chain, its links just under the reach
        drops.push_back(centre + static_cast<double>(k) * step);
      for (int k = 0; k < 20; ++k)  // and a clump round its start
        drops.push_back(centre + 8.0 * glm::dvec3(uniform() - 0.5, uniform() - 0.5, uniform()));
    }
    std::vector<std::size_t> parent(drops.size());
    for (std::size_t i = 0; i < parent.size(); ++i)
      parent[i] = i;
    const auto find = [&parent](std::size_t i) {
      while (parent[i] != i)
        i = parent[i] = parent[parent[i]];
      return i;
    };
    for (std::size_t i = 0; i < drops.size(); ++i)
      for (std::size_t j = i + 1; j < drops.size(); ++j)
        if (glm::length(drops[i] - drops[j]) < link) parent[find(i)] = find(j);
    std::size_t groups = 0;
    for (std::size_t i = 0; i < drops.size(); ++i)
      groups += find(i) == i ? 1 : 0;
    LiquidSurface liquid(options);
    liquid.update(drops);
    EXPECT_EQ(liquid.groups(), groups) << "trial " << trial;
    EXPECT_GT(groups, 3u);
    EXPECT_LT(groups, drops.size() / 4);
  }
}

TEST(LiquidSurface, ALargePoolIsDrawnOnCoarserCellsWithAboutAsManyFaces) {
  // A pool of 48 x 48 particles (2,304) at the rest spacing: past fine_particles the cells grow
  // with the square root of the count, so the pool costs the renderer a fraction of the faces it
  // would on the finest cells, and it is still one closed sheet.
  std::vector<glm::dvec3> pool;
  for (int i = 0; i < 48; ++i)
    for (int j = 0; j < 48; ++j)
      pool.push_back({2.4 * i, 2.4 * j, 0.0});
  LiquidSurface coarse;
  const std::size_t coarse_faces = coarse.update(pool).num_faces();
  expect_closed_balls(coarse.mesh());
  EXPECT_EQ(connected_parts(coarse.mesh()).size(), 1u);
  const LiquidSurfaceOptions defaults;
  const double expected =
      defaults.cell_mm * std::sqrt(2304.0 / static_cast<double>(defaults.fine_particles));
  EXPECT_NEAR(coarse.cell_mm(), std::min(expected, defaults.max_cell_mm), 1e-9);

  LiquidSurfaceOptions finest;
  finest.fine_particles = 0;
  LiquidSurface fine(finest);
  const std::size_t fine_faces = fine.update(pool).num_faces();
  EXPECT_NEAR(fine.cell_mm(), defaults.cell_mm, 1e-9);
  std::printf("2,304 particles: %zu faces on %.2f mm cells, %zu on %.2f mm\n", coarse_faces,
              coarse.cell_mm(), fine_faces, fine.cell_mm());
  EXPECT_LT(coarse_faces, fine_faces / 2);
}

}  // namespace
}  // namespace bisturi::render

namespace bisturi::runtime {
namespace {

TEST(LiquidWorker, BuildsTheNewestParticlesOnItsThreadAsTheRenderThreadWould) {
  std::vector<glm::dvec3> pool;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      pool.push_back({2.4 * i, 2.4 * j, 0.0});
  render::LiquidSurface here;
  const std::size_t faces = here.update(pool).num_faces();
  ASSERT_GT(faces, 0u);

  LiquidWorker worker;
  std::uint64_t number = 7;
  EXPECT_EQ(worker.newest(number), nullptr);  // nothing built yet
  EXPECT_EQ(number, 0u);
  worker.offer(pool);
  worker.settle();
  const std::shared_ptr<const Dlfl> first = worker.newest(number);
  ASSERT_NE(first, nullptr);
  EXPECT_EQ(number, 1u);
  EXPECT_EQ(first->num_faces(), faces);
  // The same particles again: no new build. Moved ones: a new surface, the old one still whole
  // for whoever draws it.
  worker.offer(pool);
  worker.settle();
  (void)worker.newest(number);
  EXPECT_EQ(number, 1u);
  for (glm::dvec3& p : pool)
    p.z += 5.0;
  worker.offer(pool);
  worker.settle();
  const std::shared_ptr<const Dlfl> second = worker.newest(number);
  EXPECT_EQ(number, 2u);
  EXPECT_EQ(second->num_faces(), faces);
  EXPECT_EQ(first->num_faces(), faces);
  // No particles: an empty surface.
  worker.offer({});
  worker.settle();
  EXPECT_EQ(worker.newest(number)->num_faces(), 0u);
  EXPECT_EQ(number, 3u);
}

/// The mean height of a surface's vertices (mm).
double mean_z(const Dlfl& mesh) {
  double sum = 0.0;
  std::size_t count = 0;
  for (std::uint32_t v = 0; v < mesh.vertex_capacity(); ++v)
    if (mesh.alive(VertexId(v))) {
      sum += mesh.position(VertexId(v)).z;
      ++count;
    }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

TEST(LiquidWorker, WhileTheBloodIsBehindItBuildsEveryOtherStepAndTheLastWhenItCatchesUp) {
  std::vector<std::vector<glm::dvec3>> steps(3);  // a pool at 0, 10 and 20 mm
  for (std::size_t k = 0; k < steps.size(); ++k)
    for (int i = 0; i < 6; ++i)
      for (int j = 0; j < 6; ++j)
        steps[k].push_back({2.4 * i, 2.4 * j, 10.0 * static_cast<double>(k)});
  LiquidWorker worker;
  std::uint64_t number = 0;
  const auto offer = [&](std::size_t step, bool behind) {
    worker.offer(steps[step], behind);
    worker.settle();
    return worker.newest(number);
  };
  EXPECT_EQ(offer(0, true), nullptr);  // passed over
  EXPECT_EQ(offer(0, true), nullptr);  // the same step again: still passed over
  const std::shared_ptr<const Dlfl> second = offer(1, true);
  ASSERT_NE(second, nullptr);
  EXPECT_EQ(number, 1u);
  EXPECT_NEAR(mean_z(*second), 10.0, 0.5);
  (void)offer(2, true);  // passed over
  EXPECT_EQ(number, 1u);
  // Caught up with no newer step: the one passed over is built.
  const std::shared_ptr<const Dlfl> third = offer(2, false);
  EXPECT_EQ(number, 2u);
  EXPECT_NEAR(mean_z(*third), 20.0, 0.5);
  (void)offer(2, false);  // built already
  EXPECT_EQ(number, 2u);
}

}  // namespace
}  // namespace bisturi::runtime
