// `bisturi render` frames a solid of any size (tools/bisturi/orbit_framing.h): from 0.1 mm to 2 m
// across, the orbit's first frame shows the solid in both eyes (pixels differ from the
// background), and frustum culling never drops it.

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/frame_sink.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/scene/polygon_import.h"
#include "orbit_framing.h"

namespace bisturi {
namespace {

/// An icosahedron of circumradius r about c.
Dlfl icosahedron(double r, const glm::dvec3& c) {
  const double t = (1.0 + std::sqrt(5.0)) / 2.0;
  const std::vector<glm::dvec3> v = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0},
                                     {0, -1, t}, {0, 1, t}, {0, -1, -t}, {0, 1, -t},
                                     {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
  const std::vector<std::array<std::uint32_t, 3>> f = {
      {0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
      {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
      {3, 8, 9},  {4, 9, 5},  {2, 4, 11}, {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  PolygonMesh mesh;
  for (const glm::dvec3& p : v)
    mesh.positions.push_back(c + glm::normalize(p) * r);
  for (const auto& tri : f)
    mesh.add_face({tri[0], tri[1], tri[2]});
  return import_polygons(mesh, true).mesh;
}

/// Counts, per eye, the pixels that differ from the first pixel (the background).
struct CountingSink final : render::FrameSink {
  void consume(const render::StereoFrame& frame) override {
    for (int e = 0; e < 2; ++e) {
      const auto px = frame.eye(e);
      std::size_t n = 0;
      for (std::size_t i = 4; i + 3 < px.size(); i += 4)
        n += (px[i] != px[0] || px[i + 1] != px[1] || px[i + 2] != px[2]) ? 1 : 0;
      covered[e] = n;
    }
  }
  std::size_t covered[2] = {0, 0};
};

TEST(RenderFraming, SolidsFromATenthOfAMillimetreToTwoMetresFillBothEyes) {
  std::size_t reference = 0;
  for (const double across_mm : {0.1, 1.0, 50.0, 2000.0}) {
    const double r = across_mm / 2.0;
    const glm::dvec3 c(3.0 * r, -r, 0.5 * r);  // off the origin, as files are
    const Dlfl solid = icosahedron(r, c);
    render::RendererOptions ro;
    ro.headset.eye_width = 64;
    ro.headset.eye_height = 64;
    const cli::OrbitFraming f =
        cli::frame_orbit(c - glm::dvec3(r), c + glm::dvec3(r), ro.headset.fov[0], 64.0);
    ro.headset.near_mm = f.near_mm;
    ro.headset.far_mm = f.far_mm;
    ro.headset.ipd_mm = f.ipd_mm;
    try {
      render::StereoRenderer renderer(ro);
      CountingSink sink;
      renderer.set_sink(&sink);
      renderer.add_solid(solid);
      const glm::dvec3 eye = f.centre + glm::dvec3(0.0, 0.25, 1.0) * f.distance_mm;
      const render::FrameStats stats = renderer.render(render::look_at(eye, f.centre));
      renderer.flush();
      EXPECT_GT(stats.triangles_drawn, 0u) << across_mm << " mm: culled";
      EXPECT_EQ(stats.solids_culled, 0u) << across_mm << " mm";
      // The box's diagonal spans two thirds of the view: the icosahedron covers about 6 % of each
      // eye's 4096 pixels, the same share at every size.
      EXPECT_GT(sink.covered[0], 150u) << across_mm << " mm, left eye";
      EXPECT_GT(sink.covered[1], 150u) << across_mm << " mm, right eye";
      if (reference == 0) reference = sink.covered[0];
      EXPECT_NEAR(static_cast<double>(sink.covered[0]), static_cast<double>(reference),
                  0.2 * static_cast<double>(reference))
          << across_mm << " mm: framed like the others";
    } catch (const render::NoVulkanDevice& e) {
      GTEST_SKIP() << "no Vulkan device: " << e.what();
    }
  }
}

}  // namespace
}  // namespace bisturi
