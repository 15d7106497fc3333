// The integrator's thread team (IntegratorOptions::threads, sim/src/step_threads.h): every member
// runs once per job, the parts cover the items exactly, a threaded run is bit-identical run to
// run, and it follows the single-thread run within the solver's float rounding.

#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <vector>

#include "bisturi/sim/world.h"
#include "sim_test_shapes.h"
#include "step_threads.h"

namespace bisturi::sim {
namespace {

TEST(StepThreads, EveryPartRunsOncePerJob) {
  for (unsigned threads : {1u, 2u, 3u, 5u, 8u}) {  // 8: more threads than cores here
    StepThreads team(threads);
    ASSERT_EQ(team.size(), threads);
    std::vector<std::atomic<int>> runs(threads);
    for (int job = 0; job < 300; ++job)
      team.run([&](unsigned t) { runs[t].fetch_add(1); });
    for (unsigned t = 0; t < threads; ++t)
      EXPECT_EQ(runs[t].load(), 300) << threads << " threads, member " << t;
  }
}

TEST(StepThreads, PartsCoverTheItemsOnceAndStartAligned) {
  for (std::size_t n : {0u, 1u, 63u, 64u, 1000u, 114488u}) {
    for (unsigned parts : {1u, 2u, 3u, 7u}) {
      std::size_t next = 0;
      for (unsigned t = 0; t < parts; ++t) {
        const Range r = part_of(n, parts, t, 64);
        EXPECT_EQ(r.begin, next);
        EXPECT_LE(r.begin, r.end);
        if (r.begin < n) {
          EXPECT_EQ(r.begin % 64, 0u);
        }
        next = r.end;
      }
      EXPECT_EQ(next, n);
    }
  }
}

/// A sphere with its lower half anchored, pressed by the probe for `steps` steps; its positions.
std::vector<glm::dvec3> pressed_sphere(unsigned threads, int steps) {
  WorldOptions options;
  options.integrator.threads = threads;
  SimWorld world(options);
  const std::uint32_t id = world.add_body(SoftBody(testing::sphere(20, 6.0), Material{}));
  SoftBody& body = world.body(id);
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < 0.0095) body.set_anchored(VertexId(i), true);
  }
  for (int s = 0; s < steps; ++s)
    world.step({0.0095, 0.0095, 0.0095 + 0.007 - 0.002 * std::sin(0.01 * s)});
  return body.positions();
}

TEST(SimThreads, ThreadedStepsAreDeterministicAndFollowTheSingleThreadOnes) {
  const std::vector<glm::dvec3> one = pressed_sphere(1, 300);
  const std::vector<glm::dvec3> two = pressed_sphere(2, 300);
  const std::vector<glm::dvec3> two_again = pressed_sphere(2, 300);
  const std::vector<glm::dvec3> three = pressed_sphere(3, 300);
  ASSERT_EQ(one.size(), two.size());
  EXPECT_EQ(two, two_again);  // bit for bit
  // The split sums may round differently from the single sum, so the states may differ, by
  // rounding only: far below the probe's press (measured: identical here, where the float solve
  // absorbs the double sums' last bits; the 20k bench sphere differs in the 4th digit of the
  // mean residual).
  double moved = 0.0, apart_two = 0.0, apart_three = 0.0;
  const std::vector<glm::dvec3> rest = pressed_sphere(1, 0);
  for (std::size_t i = 0; i < one.size(); ++i) {
    moved = std::max(moved, glm::length(one[i] - rest[i]));
    apart_two = std::max(apart_two, glm::length(one[i] - two[i]));
    apart_three = std::max(apart_three, glm::length(one[i] - three[i]));
  }
  EXPECT_GT(moved, 1e-4) << "the probe did not press: the comparison proves nothing";
  EXPECT_LT(apart_two, 1e-3 * moved);
  EXPECT_LT(apart_three, 1e-3 * moved);
}

}  // namespace
}  // namespace bisturi::sim
