#include "render_command.h"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <nlohmann/json.hpp>
#include <numbers>
#include <vector>

#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/runtime/render/stereo_renderer.h"
#include "bisturi/runtime/session/timing.h"
#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/phantoms.h"
#include "orbit_framing.h"
#include "progress_line.h"
#include "render_scene.h"

namespace bisturi::cli {

namespace {

using Clock = std::chrono::steady_clock;

Dlfl load_solid(const RenderOptions& options, ProgressLine& line) {
  if (!options.phantom.empty()) {
    PhantomOptions p;
    p.shape = phantom_shape_from_string(options.phantom);
    p.dims = {96, 96, 96};
    IsoSurfaceOptions iso;
    iso.progress = [&](std::size_t done, std::size_t total) { line.show("phantom", done, total); };
    return extract_isosurface(make_phantom(p), iso);
  }
  ReadOptions read;
  read.progress = [&](std::size_t done, std::size_t total) { line.show("read", done, total); };
  const MeshFile file = read_mesh(options.input, read);
  ImportOptions import;
  import.progress = [&](std::string_view stage, std::size_t done, std::size_t total) {
    line.show(stage, done, total);
};
return import_polygons(file.polygons, file.has_vertex_list, import).mesh;
}  // namespace

bool is_scene(const std::string& input) {
  return input.size() > 5 && input.substr(input.size() - 5) == ".toml";
}

/// What to draw: a scene's solids, or one solid from a mesh file or a phantom.
std::vector<SceneSolid> load_solids(const RenderOptions& options, ProgressLine& line) {
  if (is_scene(options.input)) {
    line.show("scene", 0, 1);
    return scene_solids(options.input, options.incision);
  }
  std::vector<SceneSolid> one(1);
  one[0].name = options.phantom.empty() ? options.input : options.phantom;
  one[0].mesh = load_solid(options, line);
  return one;
}

}  // namespace bisturi::cli

void add_render_command(CLI::App& app, RenderOptions& options, int (*&run)(const RenderOptions&)) {
  CLI::App* cmd = app.add_subcommand(
      "render",
      "render a stereo orbit around a solid (Vulkan, both eyes in one pass) and write PNG frames; "
      "MESH is a mesh file (.obj .ply .stl .off), a scene file (.toml) or --phantom NAME");
  auto* input = cmd->add_option("MESH", options.input,
                                "mesh file (OBJ, PLY, STL, OFF), or a scene file (.toml): its "
                                "solids as a session draws them, the structures inside them "
                                "hidden but where an incision shows them")
                    ->check(CLI::ExistingFile);
  auto* phantom = cmd->add_option("--phantom", options.phantom,
                                  "an analytic phantom's surface instead of a file (sphere, shell, "
                                  "torus, two-spheres, tube, gyroid)");
  input->excludes(phantom);
  phantom->excludes(input);
  cmd->add_option("--out", options.output, "folder for the frames (PNG) and frames.csv")
      ->required();
  cmd->add_option("--frames", options.frames, "frames in the orbit")
      ->check(CLI::Range(1u, 100000u));
  cmd->add_option("--eye-width", options.eye_width, "pixels per eye, across")
      ->check(CLI::Range(16u, 8192u));
  cmd->add_option("--eye-height", options.eye_height, "pixels per eye, down")
      ->check(CLI::Range(16u, 8192u));
  cmd->add_flag("--per-eye", options.per_eye, "one PNG per eye instead of side by side");
  cmd->add_flag("--no-culling", options.no_culling, "draw every chunk (no frustum culling)");
  cmd->add_flag("--occlusion", options.occlusion,
                "leave out what the solids in front hide (occlusion culling on the CPU)");
  cmd->add_flag("--no-lod", options.no_lod, "always draw the full-detail level");
  cmd->add_flag("--cpu", options.cpu, "render on a CPU Vulkan device (lavapipe) even with a GPU");
  cmd->add_flag("--validation", options.validation,
                "enable the Vulkan validation layer and report its message count");
  cmd->add_flag("--json", options.json, "write the summary as one JSON object on stdout");
  cmd->add_flag("--incision", options.incision,
                "scene files: cut the first solid along the scene's [procedure] cut first (its "
                "inner structures are then seen through the incision)");
  cmd->callback([&run, &options] {
    if (options.input.empty() && options.phantom.empty())
      throw CLI::ValidationError("a MESH file or --phantom NAME is required");
    if (options.incision && !is_scene(options.input))
      throw CLI::ValidationError("--incision is for scene files (.toml)");
    run = run_render;
  });
}

int run_render(const RenderOptions& options) {
  ProgressLine line;
  auto t = Clock::now();
  const std::vector<SceneSolid> solids = load_solids(options, line);
  line.done(options.phantom.empty() ? "read " + options.input : "phantom " + options.phantom,
            std::chrono::duration<double, std::milli>(Clock::now() - t).count());

  render::RendererOptions ro;
  ro.headset.eye_width = options.eye_width;
  ro.headset.eye_height = options.eye_height;
  // The orbit: around the solid's vertical (y) axis, slightly from above, framed for its size.
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (const SceneSolid& solid : solids) {
    for (std::size_t i = 0; i < solid.mesh.vertex_capacity(); ++i) {
      const VertexId v{static_cast<std::uint32_t>(i)};
      if (!solid.mesh.alive(v)) continue;
      lo = glm::min(lo, glm::dvec3(solid.mesh.position(v)));
      hi = glm::max(hi, glm::dvec3(solid.mesh.position(v)));
    }
  }
  if (!(lo.x <= hi.x)) throw std::invalid_argument("the solid has no vertices to render");
  const OrbitFraming framing = frame_orbit(lo, hi, ro.headset.fov[0], ro.headset.ipd_mm);
  const glm::dvec3 centre = framing.centre;
  const double distance = framing.distance_mm;
  ro.headset.near_mm = framing.near_mm;
  ro.headset.far_mm = framing.far_mm;
  ro.headset.ipd_mm = framing.ipd_mm;
  ro.frustum_culling = !options.no_culling;
  if (options.occlusion) ro.occlusion_cells = render::kOcclusionCells;
  ro.level_of_detail = !options.no_lod;
  ro.field_lamp = true;  // nearer surfaces brighter: the orbit reads in depth
  ro.validation = options.validation;
  if (options.cpu) ro.device = render::DevicePreference::Cpu;
  render::StereoRenderer renderer(ro);
  t = Clock::now();
  line.show("levels of detail", 0, 1);
  std::vector<render::SolidId> ids;
  for (const SceneSolid& solid : solids)
    ids.push_back(renderer.add_solid(solid.mesh, solid.material));
  for (std::size_t k = 0; k < solids.size(); ++k) {
    if (solids[k].enclosed_by >= 0)
      renderer.set_enclosed_by(ids[k], ids[static_cast<std::size_t>(solids[k].enclosed_by)]);
  }
  const double levels_ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  line.done("levels of detail", levels_ms);

  render::PngSink sink(
      options.output,
      {options.per_eye ? render::PngLayout::PerEye : render::PngLayout::SideBySide, 1});
  renderer.set_sink(&sink);

  renderer.set_sink(&sink);
  std::vector<double> frame_ms;
  std::size_t draw_calls = 0, chunks_culled = 0, chunks_drawn = 0, triangles = 0;
  std::size_t culled_frustum = 0, culled_occlusion = 0, culled_portal = 0;
  std::size_t empty_frames = 0;
  const auto start = Clock::now();
  auto previous = start;
  for (std::uint32_t i = 0; i < options.frames; ++i) {
    const double angle = 2.0 * std::numbers::pi * i / options.frames;
    const glm::dvec3 eye = centre + glm::dvec3(std::sin(angle) * distance, 0.25 * distance,
                                               std::cos(angle) * distance);
    const render::HeadPose pose = render::look_at(eye, centre);
    const render::FrameStats stats = renderer.render(pose);
    draw_calls += stats.draw_calls;
    chunks_culled += stats.chunks_culled;
    chunks_drawn += stats.chunks_drawn;
    triangles += stats.triangles_drawn;
    culled_frustum += stats.triangles_culled_frustum;
    culled_occlusion += stats.triangles_culled_occlusion;
    culled_portal += stats.triangles_culled_portal;
    if (stats.triangles_drawn == 0) {
      if (empty_frames == 0)
        std::cerr << "bisturi render: frame " << i << " draws nothing: the solid is not in view\n";
      ++empty_frames;
    }
    const auto now = Clock::now();
    frame_ms.push_back(std::chrono::duration<double, std::milli>(now - previous).count());
    previous = now;
    line.show("render", i + 1, options.frames);
  }
  renderer.flush();
  sink.finish();
  const double total_s = std::chrono::duration<double>(Clock::now() - start).count();
  line.clear();

  const double n = options.frames;
  const nlohmann::json summary = {
      {"input", options.phantom.empty() ? options.input : "phantom:" + options.phantom},
      {"out", options.output},
      {"device", renderer.device_name()},
      {"device_is_cpu", renderer.device_is_cpu()},
      {"eye_width", options.eye_width},
      {"eye_height", options.eye_height},
      {"frames", options.frames},
      {"images", sink.images_written()},
      {"fps", n / total_s},
      {"frame_ms_p50", runtime::percentile(frame_ms, 50.0)},
      {"frame_ms_p99", runtime::percentile(frame_ms, 99.0)},
      {"motion_to_photon_ms_p50", runtime::percentile(sink.latencies_ms(), 50.0)},
      {"motion_to_photon_ms_p99", runtime::percentile(sink.latencies_ms(), 99.0)},
      {"draw_calls_per_frame", static_cast<double>(draw_calls) / n},
      {"chunks_drawn_per_frame", static_cast<double>(chunks_drawn) / n},
      {"chunks_culled_per_frame", static_cast<double>(chunks_culled) / n},
      {"culled_chunks", chunks_culled},
      {"triangles_per_frame", static_cast<double>(triangles) / n},
      {"culled_triangles_per_frame",
       {{"frustum", static_cast<double>(culled_frustum) / n},
        {"occlusion", static_cast<double>(culled_occlusion) / n},
        {"portal", static_cast<double>(culled_portal) / n}}},
      {"solids", solids.size()},
      {"levels", renderer.levels(ids.front()).level_count()},
      {"empty_frames", empty_frames},
      {"solid_size", {hi.x - lo.x, hi.y - lo.y, hi.z - lo.z}},
      {"near_mm", ro.headset.near_mm},
      {"far_mm", ro.headset.far_mm},
      {"ipd_mm", ro.headset.ipd_mm},
      {"levels_ms", levels_ms},
      {"validation_messages", renderer.validation_messages()}};
  if (options.json) {
    std::cout << summary.dump(2) << "\n";
  } else {
    std::cout << options.frames << " frames of 2 x " << options.eye_width << " x "
              << options.eye_height << " on " << renderer.device_name() << " -> " << options.output
              << "\n  " << summary["fps"].get<double>() << " frames/s, frame time p50 "
              << summary["frame_ms_p50"].get<double>() << " ms, p99 "
              << summary["frame_ms_p99"].get<double>() << " ms (PNG writing included)\n  "
              << summary["draw_calls_per_frame"].get<double>() << " draw calls, "
              << summary["triangles_per_frame"].get<double>() << " triangles and "
              << summary["chunks_culled_per_frame"].get<double>() << " culled chunks per frame\n  "
              << "triangles culled per frame: " << static_cast<double>(culled_frustum) / n
              << " by the frusta, " << static_cast<double>(culled_occlusion) / n
              << " hidden by solids in front or round them, "
              << static_cast<double>(culled_portal) / n << " seen through no opening\n";
  }
  if (empty_frames > 0)
    std::cerr << "bisturi render: " << empty_frames << " of " << options.frames
              << " frames drew nothing\n";
  return renderer.validation_messages() == 0 ? 0 : 3;
}

}  // namespace bisturi::cli
