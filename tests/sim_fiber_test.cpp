// What the multirate far field is built from: fibers (sim/src/fiber.h) that stop part-way and
// go on where they stopped, a sequential team that runs its parts in turn with a hook after each,
// and a deep copy of a soft body that a solver can advance apart from the original.

#include <gtest/gtest.h>

#include <stdexcept>
#include <string>
#include <vector>

#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "fiber.h"
#include "sim_test_shapes.h"
#include "step_threads.h"

namespace bisturi::sim {
namespace {

TEST(Fiber, SuspendsAndResumesWhereItStopped) {
  Fiber fiber;
  std::vector<int> trace;
  fiber.start([&] {
    for (int i = 0; i < 3; ++i) {
      trace.push_back(i);
      EXPECT_EQ(Fiber::current(), &fiber);
      Fiber::suspend();
    }
    trace.push_back(99);
  });
  EXPECT_EQ(Fiber::current(), nullptr);
  for (int i = 0; i < 3; ++i) {
    EXPECT_FALSE(fiber.resume());
    EXPECT_TRUE(fiber.part_way());
    EXPECT_EQ(trace.back(), i);
  }
  EXPECT_TRUE(fiber.resume());
  EXPECT_FALSE(fiber.part_way());
  EXPECT_EQ(trace, (std::vector<int>{0, 1, 2, 99}));
  // The same fiber runs another function, with a deep stack (recursion in its own stack).
  std::function<int(int)> depth = [&](int n) {
    volatile char pad[1024];
    pad[0] = static_cast<char>(n);
    return n == 0 ? int(pad[0]) : 1 + depth(n - 1);
  };
  int result = 0;
  fiber.start([&] { result = depth(200); });
  EXPECT_TRUE(fiber.resume());
  EXPECT_EQ(result, 200);
}

TEST(Fiber, AnExceptionComesOutOfResume) {
  Fiber fiber;
  fiber.start([] {
    Fiber::suspend();
    throw std::runtime_error("inside");
  });
  EXPECT_FALSE(fiber.resume());
  EXPECT_THROW(fiber.resume(), std::runtime_error);
  EXPECT_FALSE(fiber.part_way());
  EXPECT_THROW(Fiber::suspend(), std::logic_error);  // not in a fiber
}

TEST(Fiber, ADestroyedFiberRunsToItsEnd) {
  bool ended = false;
  {
    Fiber fiber;
    fiber.start([&] {
      std::string held(1000, 'x');  // a live object on the fiber's stack
      Fiber::suspend();
      ended = held.size() == 1000;
    });
    fiber.resume();
    EXPECT_THROW(fiber.start([] {}), std::logic_error);  // part-way
  }
  EXPECT_TRUE(ended);
}

TEST(StepThreads, ASequentialTeamRunsItsPartsInTurnWithTheHookAfterEach) {
  std::vector<std::string> trace;
  StepThreads team(4, [&] { trace.emplace_back("hook"); });
  EXPECT_TRUE(team.sequential());
  EXPECT_EQ(team.size(), 4u);
  team.run([&](unsigned t) { trace.push_back(std::to_string(t)); });
  EXPECT_EQ(trace, (std::vector<std::string>{"0", "hook", "1", "hook", "2", "hook", "3", "hook"}));
  EXPECT_FALSE(StepThreads(3).sequential());
}

TEST(SoftBody, ACopyIsIndependentAndStepsAsTheOriginal) {
  SoftBody original(testing::sphere(16, 6.0), Material{});
  original.set_anchored(VertexId(0), true);
  original.set_velocity(VertexId(5), {0.0, 0.0, 0.01});
  SoftBody copy(original);
  EXPECT_EQ(copy.state_hash(), original.state_hash());
  EXPECT_EQ(copy.springs().size(), original.springs().size());
  EXPECT_TRUE(copy.anchored(VertexId(0)));
  EXPECT_NE(copy.lineage(), original.lineage());
  EXPECT_NE(copy.derived_generation(), original.derived_generation());
  // Its state lives in its own mesh: editing one leaves the other.
  copy.set_position(VertexId(3), {1.0, 2.0, 3.0});
  EXPECT_NE(original.position(VertexId(3)), copy.position(VertexId(3)));
  copy.set_position(VertexId(3), original.position(VertexId(3)));
  // The same steps give the same bits, each with its own integrator.
  IntegratorOptions options;
  ImplicitIntegrator a, b;
  std::vector<SimEvent> events;
  for (int s = 0; s < 20; ++s) {
    original.add_force(VertexId(7), {0.0, 0.0, -0.01});
    copy.set_loads_from(original);
    a.step(original, options, events);
    b.step(copy, options, events);
  }
  EXPECT_TRUE(events.empty());
  EXPECT_EQ(copy.state_hash(), original.state_hash());
}

}  // namespace
}  // namespace bisturi::sim
