// The field's shading at rest (runtime/src/session/field_occlusion.h): the drape under a solid
// lies in its soft shadow and darkens near it; far from it the drape is open and lit; a solid's
// underside close over the drape is occluded, its top open.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <vector>

#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "bisturi/sim/world.h"
#include "session/field_occlusion.h"

namespace bisturi::runtime {
namespace {

/// A ball of radius 20 mm centred 22 mm above z = 0 (the drape goes 2 mm under it, at z = 0).
sim::SimWorld ball_world() {
  PhantomOptions p;
  p.shape = PhantomShape::Sphere;
  p.dims = {48, 48, 48};
  p.spacing = glm::dvec3(1.0);
  p.a = 20.0;
  Dlfl ball = extract_isosurface(make_phantom(p));
  const glm::dvec3 centre(23.5);
  for (auto& x : ball.positions())
    x = x - centre + glm::dvec3(0.0, 0.0, 22.0);
  sim::WorldOptions options;
  sim::SimWorld world(options);
  world.add_body(sim::SoftBody(std::move(ball), sim::Material{}));
  world.prepare();
  return world;
}

/// The value at the drape vertex nearest (x, y).
float at(const FieldShading& s, double x, double y) {
  std::uint32_t best = 0;
  double best_d = 1e30;
  for (std::uint32_t v = 0; v < s.drape.vertex_capacity(); ++v) {
    if (!s.drape.alive(VertexId(v))) continue;
    const glm::dvec3& p = s.drape.position(VertexId(v));
    const double d = glm::length(glm::dvec2(p.x - x, p.y - y));
    if (d < best_d) {
      best_d = d;
      best = v;
    }
  }
  return s.drape_open[best];
}

TEST(FieldShading, TheDrapeLiesInASolidsSoftShadowAndIsOpenFarFromIt) {
  const sim::SimWorld world = ball_world();
  const FieldShading s = shade_field(world, {nullptr}, kDrapeBelow_mm);
  EXPECT_NEAR(s.drape_z_mm, 0.0, 0.6);
  const float under = at(s, 0.0, 0.0);
  const float edge = at(s, 24.0, 0.0);  // just past the ball's rim
  const float far = at(s, 70.0, 0.0);
  std::printf("drape open: %.2f under the ball, %.2f past its rim, %.2f far from it\n", under, edge,
              far);
  EXPECT_LT(under, 0.5F);
  EXPECT_LT(under, edge);
  EXPECT_LT(edge, far);
  EXPECT_GT(far, 0.99F);
  // The ball's own vertices: its underside over the drape occluded, its top open.
  ASSERT_EQ(s.solid_open.size(), 1u);
  const sim::SoftBody& body = world.body(0);
  float lowest = 1.0F, top = 0.0F;
  for (std::uint32_t v = 0; v < body.mesh().vertex_capacity(); ++v) {
    if (!body.mesh().alive(VertexId(v))) continue;
    const double z = body.positions()[v].z * 1e3;
    if (z < 4.0) lowest = std::min(lowest, s.solid_open[0][v]);
    if (z > 40.0) top = std::max(top, s.solid_open[0][v]);
  }
  EXPECT_LT(lowest, 0.6F);
  EXPECT_FLOAT_EQ(top, 1.0F);
}

}  // namespace
}  // namespace bisturi::runtime
