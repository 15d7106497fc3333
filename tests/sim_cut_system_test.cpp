// After a cut the integrator updates its free system around the cut instead of building it
// again: the rows, their entries and the spring sets must be what a build from scratch gives,
// entry for entry (so the steps after the cut are bit for bit those of a rebuilt system).

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "bisturi/scene/dlfl_validate.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/integrator.h"
#include "bisturi/sim/soft_body.h"
#include "sim_test_shapes.h"

namespace bisturi::sim {
namespace {

constexpr double kCentre = 0.0115;  // the 8 mm test sphere's centre (m)
constexpr double kRadius = 0.008;

/// Blade points along an arc over the sphere from the polar angle `from` to `to` (radians), in
/// the vertical plane at azimuth `azimuth`.
std::vector<glm::dvec3> arc(double from, double to, double azimuth) {
  std::vector<glm::dvec3> points;
  for (int i = 0; i <= 6; ++i) {
    const double a = from + (to - from) * i / 6.0;
    points.push_back(glm::dvec3(kCentre) + kRadius * glm::dvec3(std::sin(a) * std::cos(azimuth),
                                                                std::sin(a) * std::sin(azimuth),
                                                                std::cos(a)));
  }
  return points;
}

TEST(SimCutSystem, TheSystemUpdatedAroundCutsIsTheOneBuiltFromScratch) {
  SoftBody body(testing::sphere(24, 8.0), Material{});
  // The lower part anchored: rows with springs to fixed vertices, and fixed springs.
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < kCentre - 0.004) body.set_anchored(VertexId(i), true);
  }
  ImplicitIntegrator integrator;
  IntegratorOptions options;
  std::vector<SimEvent> events;
  integrator.prepare(body, options);
  ASSERT_EQ(integrator.check_free_system(body), "");
  // Over the top, beside the first, and down into the anchored part.
  const std::vector<std::vector<glm::dvec3>> blades{arc(-0.5, 0.5, 0.0), arc(0.4, 1.2, 1.6),
                                                    arc(1.6, 2.6, 3.4)};
  std::uint64_t updated = integrator.systems_updated();
  for (std::size_t c = 0; c < blades.size(); ++c) {
    ASSERT_NO_THROW(cut_surface(body, blades[c])) << "cut " << c;
    ASSERT_TRUE(validate(body.mesh()).ok());
    integrator.prepare(body, options);
    EXPECT_EQ(integrator.check_free_system(body), "") << "cut " << c;
    EXPECT_EQ(integrator.systems_updated(), ++updated) << "cut " << c;
    for (int s = 0; s < 5; ++s)
      (void)integrator.step(body, options, events, 0, static_cast<std::uint64_t>(s));
    EXPECT_EQ(integrator.check_free_system(body), "") << "cut " << c << ", after steps";
  }
  EXPECT_TRUE(events.empty());
}

TEST(SimCutSystem, ACutAfterAnAnchorChangeBuildsTheSystemAgain) {
  SoftBody body(testing::sphere(24, 8.0), Material{});
  ImplicitIntegrator integrator;
  integrator.prepare(body);
  // A vertex far from the cut becomes fixed between the system's build and the cut: the old rows
  // do not hold, and the update gives way to a full build.
  for (std::uint32_t i = 0; i < body.mesh().vertex_capacity(); ++i) {
    if (body.position(VertexId(i)).z < kCentre - 0.007) body.set_anchored(VertexId(i), true);
  }
  const std::uint64_t updated = integrator.systems_updated();
  cut_surface(body, arc(-0.5, 0.5, 0.0));
  integrator.prepare(body);
  EXPECT_EQ(integrator.systems_updated(), updated);
  EXPECT_EQ(integrator.check_free_system(body), "");
}

}  // namespace
}  // namespace bisturi::sim
