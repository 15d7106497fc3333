// Blood as position-based fluid particles (sim/blood.h): poured onto a slab of tissue it lands,
// spreads, pools on top and drains off its edges; every particle is accounted for, none ends a
// step inside the tissue, and the same pour gives the same particles.

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>

#include <vector>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"
#include "bisturi/sim/blood.h"
#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

/// A rigid 20 x 20 x 4 mm slab, its top at z = 4 mm.
SimWorld slab_world() {
  WorldOptions options;
  options.integrator.gravity_m_s2 = glm::dvec3(0.0);
  SimWorld world(options);
  SoftBody body(build_oriented_manifold(cube_mesh(Dlfl::Vec3(0.0), 20.0)),
                testing::firm_material());
  for (auto& p : body.positions())
    p.z *= 4.0 / 20.0;
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i)
    body.set_anchored(VertexId(i), true);
  world.add_body(std::move(body));
  world.prepare();
  return world;
}

struct Pour {
  std::vector<glm::dvec3> final_positions;
  BloodCounts counts;
  int steps_with_a_particle_inside = 0;
  bool accounted_every_step = true;
  std::size_t most_particles = 0;
  double top_z = 0.0, lo_x = 0.0, hi_x = 0.0;
};

/// 5 ml/s for `emit_steps` steps (0.4 s) from 10 mm above the slab's centre, then on to 1.2 s;
/// 90 steps a second; at most max_particles in the field.
Pour pour(double offset_x_mm = 0.0, std::size_t max_particles = 5000, int emit_steps = 36,
          unsigned threads = 1) {
  SimWorld world = slab_world();
  const SoftBody& slab = world.body(0);
  glm::dvec3 lo(1e9), hi(-1e9);
  for (const glm::dvec3& p : slab.positions()) {
    lo = glm::min(lo, p);
    hi = glm::max(hi, p);
  }
  BloodOptions options;
  options.max_particles = max_particles;
  options.threads = threads;
  options.floor_z_m = lo.z - 0.02;
  options.field_min_m = lo - glm::dvec3(0.005);  // off the slab's edge and 5 mm on: drained
  options.field_max_m = hi + glm::dvec3(0.005);
  Blood blood(options);
  const BloodSurface surface{&slab, &world.bvh(0)};
  const BloodSource source{
      {0.5 * (lo.x + hi.x) + offset_x_mm * 1e-3, 0.5 * (lo.y + hi.y), hi.z + 0.010},
      {0.0, 0.0, -1.0}};
  Pour r;
  r.top_z = hi.z;
  r.lo_x = lo.x;
  r.hi_x = hi.x;
  const double dt = 1.0 / 90.0;
  for (int k = 0; k < 108; ++k) {
    if (k < emit_steps) (void)blood.emit({&source, 1}, 5e-6, 0.2, dt);
    r.most_particles = std::max(r.most_particles, blood.positions().size());
    blood.step(dt, {&surface, 1});
    const BloodCounts& c = blood.counts();
    r.accounted_every_step =
        r.accounted_every_step && c.emitted == c.in_flight + c.pooled + c.drained + c.recycled;
    bool inside = false;
    for (const glm::dvec3& p : blood.positions()) {
      const SurfacePoint q = world.bvh(0).closest_point(slab, p, 0.006);
      inside = inside || (q.found && glm::dot(p - q.point_m, q.normal) < 0.0);
    }
    if (inside) ++r.steps_with_a_particle_inside;
  }
  r.final_positions = blood.positions();
  r.counts = blood.counts();
  return r;
}

TEST(Blood, EveryParticleIsAccountedForAndNoneEndsAStepInsideTheTissue) {
  const Pour r = pour();
  EXPECT_GT(r.counts.emitted, 100u);
  EXPECT_TRUE(r.accounted_every_step) << "emitted = in flight + pooled + drained + recycled";
  EXPECT_EQ(r.steps_with_a_particle_inside, 0);
}

TEST(Blood, AtItsLimitTheOldestPoolMakesRoomAndTheBleedingGoesOn) {
  // 60 particles at most, poured for the whole 1.2 s (about 430 particles' worth): the field
  // never holds more, the flow goes on (while all 60 are still in flight there is nothing to
  // take, and it waits), and what was taken is counted. Without recycling it stops at 60.
  const Pour r = pour(0.0, 60, 108);
  EXPECT_LE(r.most_particles, 60u);
  EXPECT_GT(r.counts.emitted, 120u) << "the bleeding went on past the limit";
  EXPECT_GT(r.counts.recycled, 100u);
  EXPECT_TRUE(r.accounted_every_step) << "emitted = in flight + pooled + drained + recycled";
  EXPECT_EQ(r.steps_with_a_particle_inside, 0);
}

TEST(Blood, ItPoolsOnTheSurfaceWhereItLands) {
  const Pour r = pour();
  EXPECT_GT(r.counts.pooled, r.counts.emitted / 4) << "most come to rest";
  std::size_t on_top = 0;
  for (const glm::dvec3& p : r.final_positions)
    on_top += p.z > r.top_z && p.z < r.top_z + 0.008 ? 1 : 0;
  EXPECT_GT(on_top, r.final_positions.size() / 2) << "on the slab's top, not floating";
}

TEST(Blood, PouredAtTheEdgeSomeRunsOffAndDrains) {
  const Pour r = pour(9.0);  // 1 mm from the slab's edge
  EXPECT_GT(r.counts.drained, 0u);
  EXPECT_TRUE(r.accounted_every_step);
}

TEST(Blood, TheSamePourGivesTheSameParticles) {
  const Pour a = pour(), b = pour();
  ASSERT_EQ(a.final_positions.size(), b.final_positions.size());
  for (std::size_t i = 0; i < a.final_positions.size(); ++i)
    EXPECT_EQ(a.final_positions[i], b.final_positions[i]);
}

TEST(Blood, TwoThreadsGiveTheSameParticlesAsOne) {
  // The pairs and particles are cut into the same parts whatever the thread count, each part
  // summed on its own: which thread runs a part changes nothing, to the bit.
  const Pour one = pour(), two = pour(0.0, 5000, 36, 2);
  EXPECT_GT(one.counts.emitted, 100u);
  EXPECT_EQ(one.counts.pooled, two.counts.pooled);
  ASSERT_EQ(one.final_positions.size(), two.final_positions.size());
  for (std::size_t i = 0; i < one.final_positions.size(); ++i)
    EXPECT_EQ(one.final_positions[i], two.final_positions[i]) << i;
  EXPECT_EQ(two.steps_with_a_particle_inside, 0);
}

TEST(Blood, AnOpeningWithNoPlaceOrDirectionEmitsNothing) {
  // An opening cut down to nothing gives a source with no direction, or no place at all: it is
  // passed over, the good source bleeds on, and every particle stays a number.
  Blood blood;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::array<BloodSource, 3> sources{BloodSource{{nan, 0.0, 0.0}, {0.0, 0.0, 1.0}},
                                           BloodSource{{0.0, 0.0, 0.0}, {0.0, 0.0, 0.0}},
                                           BloodSource{{0.0, 0.0, 0.01}, {0.0, 0.0, 1.0}}};
  std::size_t made = 0;
  for (int s = 0; s < 20; ++s) {
    made += blood.emit(sources, 2e-5, 0.1, 0.002);
    blood.step(0.002, {});
  }
  EXPECT_GT(made, 10u);
  for (const glm::dvec3& p : blood.positions())
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
  const BloodCounts& c = blood.counts();
  EXPECT_EQ(c.emitted, c.in_flight + c.pooled + c.drained + c.recycled);
  const std::array<BloodSource, 1> broken{sources[1]};
  EXPECT_EQ(blood.emit(broken, 2e-5, 0.1, 0.002), 0u);
}

}  // namespace
}  // namespace bisturi::sim
