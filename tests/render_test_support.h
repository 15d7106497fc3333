#pragma once
// What the image tests of the renderer share: a capturing sink, a sphere in millimetres, a
// validated renderer on whatever Vulkan device there is (lavapipe without a GPU).

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"

namespace bisturi::render::testing {

/// Keeps the last frame's pixels (RGBA, both eyes).
struct Capture : FrameSink {
  std::vector<std::uint8_t> pixels;
  std::uint32_t width = 0, height = 0;
  std::uint64_t frames = 0;
  void consume(const StereoFrame& frame) override {
    pixels.assign(frame.pixels.begin(), frame.pixels.end());
    width = frame.eye_width;
    height = frame.eye_height;
    ++frames;
  }
  [[nodiscard]] const std::uint8_t* at(int eye, std::uint32_t x, std::uint32_t y) const {
    return &pixels[((static_cast<std::size_t>(eye) * height + y) * width + x) * 4];
  }
};

/// A marching-cubes sphere (phantom) moved to `centre` with `radius` (mm).
inline Dlfl sphere_mm(const glm::dvec3& centre, double radius, int dims = 40) {
  PhantomOptions p;
  p.shape = PhantomShape::Sphere;
  p.dims = {std::int64_t{dims}, std::int64_t{dims}, std::int64_t{dims}};
  p.spacing = glm::dvec3(20.0 / dims);
  p.a = 8.0;
  Dlfl mesh = extract_isosurface(make_phantom(p));
  const glm::dvec3 phantom_centre((dims - 1) * (20.0 / dims) / 2.0);
  for (auto& x : mesh.positions())
    x = centre + (x - phantom_centre) * (radius / 8.0);
  return mesh;
}

inline HeadsetDescription square_headset(std::uint32_t size) {
  HeadsetDescription h;
  h.eye_width = size;
  h.eye_height = size;
  h.ipd_mm = 64.0;
  return h;  // +-45 degrees per eye, symmetric
}

inline HeadPose at_origin() {
  HeadPose pose;  // looking down -z, y up
  pose.sample_time = PoseClock::now();
  return pose;
}

/// Projects a world point into an eye's pixels (x right, y down) seen from `pose`.
inline glm::dvec2 project(const HeadsetDescription& h, const HeadPose& pose, int eye,
                          const glm::dvec3& p) {
  const auto views = eye_views(h, pose);
  const glm::dvec4 clip = views[static_cast<std::size_t>(eye)].view_projection * glm::dvec4(p, 1.0);
  return {(clip.x / clip.w * 0.5 + 0.5) * h.eye_width,
          (clip.y / clip.w * 0.5 + 0.5) * h.eye_height};
}

/// Distance (pixels) from q to the nearest point of a polyline.
inline double distance_to_polyline(const std::vector<glm::dvec2>& line, const glm::dvec2& q) {
  double best = 1e30;
  for (std::size_t i = 0; i + 1 < line.size(); ++i) {
    const glm::dvec2 a = line[i], d = line[i + 1] - line[i];
    const double t = glm::clamp(glm::dot(q - a, d) / std::max(glm::dot(d, d), 1e-12), 0.0, 1.0);
    best = std::min(best, glm::length(q - (a + t * d)));
  }
  return best;
}

/// Renderers with validation on; each test ends with no validation message.
class RendererFixture : public ::testing::Test {
 protected:
  StereoRenderer* make(RendererOptions options, std::uint32_t size) {
    options.headset = square_headset(size);
    options.validation = true;
    try {
      renderers_.push_back(std::make_unique<StereoRenderer>(options));
      return renderers_.back().get();
    } catch (const NoVulkanDevice& e) {
      skipped_ = e.what();
      return nullptr;
    }
  }
  void TearDown() override {
    for (const auto& r : renderers_) {
      std::string log;
      for (const std::string& m : r->validation_log())
        log += m + "\n";
      EXPECT_EQ(r->validation_messages(), 0u) << log;
    }
  }
  std::vector<std::unique_ptr<StereoRenderer>> renderers_;
  std::string skipped_;
};

#define REQUIRE_RENDERER(r) \
  if (!(r)) GTEST_SKIP() << "no Vulkan device, rendering not tested: " << skipped_

}  // namespace bisturi::render::testing
