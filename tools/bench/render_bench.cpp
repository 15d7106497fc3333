// Stereo rendering throughput: frames per second and frame-time p99 of the multiview renderer on
// the Vulkan device at hand (lavapipe without a GPU), for scenes of about 100k and 1M triangles at
// 2 x 1024 x 1024 and 2 x 1440 x 1600, naive (every triangle of every solid, no culling, no level
// of detail) against frustum-culled + LOD, and that against frustum-culled + LOD + occlusion
// culling, all in one run; reported as ratios. Frames are read back into
// host memory as the headless sink needs them (no PNG encoding). Not a test; run by hand:
//   build/bin/render_bench [--frames N] [--quick] [--eye PIXELS]

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <numbers>
#include <string>
#include <vector>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/runtime/session/timing.h"
#include "bisturi/scene/oriented_builder.h"
#include "bisturi/scene/shapes.h"

namespace {

using namespace bisturi;
using Clock = std::chrono::steady_clock;

struct CountingSink : render::FrameSink {
  std::size_t frames = 0;
  void consume(const render::StereoFrame& frame) override {
    frames += frame.pixels.empty() ? 0 : 1;
  }
};

/// A 4 x 4 field of tori (organs on a table, 160 mm apart), `triangles` in all.
std::vector<Dlfl> make_scene(std::size_t triangles) {
  const std::size_t per_solid = triangles / 16;
  // 2 nu nv triangles with nu = 5 nv.
  const auto nv = static_cast<std::size_t>(std::sqrt(static_cast<double>(per_solid) / 10.0));
  std::vector<Dlfl> solids;
  for (int i = 0; i < 16; ++i) {
    PolygonMesh torus = torus_mesh(50.0, 18.0, 5 * nv, nv, true);
    const glm::dvec3 at(160.0 * (i % 4 - 1.5), 0.0, 160.0 * (i / 4 - 1.5));
    // The torus lies in the z = 0 plane: turn it to lie flat (y up) and place it.
    for (auto& p : torus.positions)
      p = at + glm::dvec3(p.x, p.z, -p.y);
    solids.push_back(build_oriented_manifold(torus));
  }
  return solids;
}

struct Result {
  double fps = 0, p50 = 0, p99 = 0, draw_calls = 0, triangles = 0, culled_chunks = 0;
  double cpu_ms = 0, wait_ms = 0, upload_mb = 0, index_buffers_made = 0;
};

enum class Mode { Naive, CullLod, Occlusion };

Result run(const std::vector<Dlfl>& scene, std::uint32_t w, std::uint32_t h, Mode mode,
           int frames) {
  const bool optimised = mode != Mode::Naive;
  render::RendererOptions o;
  o.headset.eye_width = w;
  o.headset.eye_height = h;
  o.frustum_culling = optimised;
  o.level_of_detail = optimised;
  o.levels.derived_levels = optimised;
  if (mode == Mode::Occlusion) o.occlusion_cells = render::kOcclusionCells;
  render::StereoRenderer renderer(o);
  for (const Dlfl& s : scene)
    renderer.add_solid(s);
  CountingSink sink;
  renderer.set_sink(&sink);
  // A surgeon's view: eyes 300 mm above the table, looking at its middle, moving slowly
  // around it (a quarter turn over the run).
  const auto pose = [&](int i) {
    const double a = 0.5 * std::numbers::pi * i / std::max(frames, 1);
    return render::look_at({300.0 * std::sin(a), 300.0, 300.0 * std::cos(a)}, {0.0, 0.0, 0.0});
  };
  for (int i = 0; i < 3; ++i)
    renderer.render(pose(i));  // warm-up
  renderer.flush();
  Result r;
  std::vector<double> ms;
  const auto start = Clock::now();
  auto previous = start;
  for (int i = 0; i < frames; ++i) {
    const render::FrameStats s = renderer.render(pose(i));
    r.draw_calls += static_cast<double>(s.draw_calls);
    r.triangles += static_cast<double>(s.triangles_drawn);
    r.culled_chunks += static_cast<double>(s.chunks_culled);
    r.cpu_ms += s.cpu_ms;
    r.wait_ms += s.wait_ms;
    r.upload_mb += static_cast<double>(s.vertex_bytes_uploaded) * 1e-6;
    r.index_buffers_made += static_cast<double>(s.index_buffers_rebuilt);
    const auto now = Clock::now();
    ms.push_back(std::chrono::duration<double, std::milli>(now - previous).count());
    previous = now;
  }
  renderer.flush();
  const double seconds = std::chrono::duration<double>(Clock::now() - start).count();
  r.fps = frames / seconds;
  r.p50 = runtime::percentile(ms, 50.0);
  r.p99 = runtime::percentile(ms, 99.0);
  r.draw_calls /= frames;
  r.triangles /= frames;
  r.culled_chunks /= frames;
  r.cpu_ms /= frames;
  r.wait_ms /= frames;
  r.upload_mb /= frames;
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  int frames = 40;
  bool quick = false;
  std::uint32_t eye = 0;  // 0: the headset sizes
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--frames") == 0 && i + 1 < argc) frames = std::atoi(argv[++i]);
    if (std::strcmp(argv[i], "--quick") == 0) quick = true;
    if (std::strcmp(argv[i], "--eye") == 0 && i + 1 < argc)
      eye = static_cast<std::uint32_t>(std::atoi(argv[++i]));
  }
  try {
    {
      render::RendererOptions probe;
      probe.headset.eye_width = probe.headset.eye_height = 16;
      render::StereoRenderer r(probe);
      std::printf("device: %s\n", r.device_name().c_str());
    }
    const std::vector<std::size_t> sizes =
        quick ? std::vector<std::size_t>{100000} : std::vector<std::size_t>{100000, 1000000};
    const std::vector<std::array<std::uint32_t, 2>> resolutions =
        eye > 0 ? std::vector<std::array<std::uint32_t, 2>>{{eye, eye}}
                : std::vector<std::array<std::uint32_t, 2>>{{1024, 1024}, {1440, 1600}};
    // cpu ms: the renderer's own work per frame (plan, stream, record, submit); wait ms: waiting
    // for the frame slot's previous frame (GPU work, read back, sink); MB up: vertex bytes
    // streamed per frame; new ib: index buffers made during the timed frames.
    std::printf("%-9s %-11s %-9s %8s %9s %9s %8s %11s %9s %7s %7s %7s %6s\n", "triangles",
                "per eye", "mode", "fps", "p50 ms", "p99 ms", "draws", "tris drawn", "culled",
                "cpu ms", "wait ms", "MB up", "new ib");
    for (const std::size_t n : sizes) {
      const std::vector<Dlfl> scene = make_scene(n);
      for (const auto& res : resolutions) {
        const Result naive = run(scene, res[0], res[1], Mode::Naive, frames);
        const Result fast = run(scene, res[0], res[1], Mode::CullLod, frames);
        const Result occluded = run(scene, res[0], res[1], Mode::Occlusion, frames);
        for (const auto* r : {&naive, &fast, &occluded}) {
          std::printf(
              "%-9zu %4ux%-6u %-9s %8.1f %9.1f %9.1f %8.1f %11.0f %9.1f %7.2f %7.2f %7.1f %6.0f\n",
              n, res[0], res[1],
              r == &naive  ? "naive"
              : r == &fast ? "cull+lod"
                           : "+occlude",
              r->fps, r->p50, r->p99, r->draw_calls, r->triangles, r->culled_chunks, r->cpu_ms,
              r->wait_ms, r->upload_mb, r->index_buffers_made);
        }
        std::printf("  ratio cull+lod / naive: fps x%.2f, p99 frame time x%.2f\n",
                    fast.fps / naive.fps, fast.p99 / naive.p99);
        std::printf("  ratio +occlude / cull+lod: fps x%.2f, p99 frame time x%.2f, cpu ms x%.2f\n",
                    occluded.fps / fast.fps, occluded.p99 / fast.p99,
                    occluded.cpu_ms / fast.cpu_ms);
        std::fflush(stdout);
      }
    }
  } catch (const render::NoVulkanDevice& e) {
    std::fprintf(stderr, "render_bench: no Vulkan device: %s\n", e.what());
    return 2;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "render_bench: %s\n", e.what());
    return 1;
  }
  return 0;
}
