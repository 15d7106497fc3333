#pragma once
// `bisturi render MESH --out DIR [--frames N] [--eye-width W --eye-height H] [--json]`:
// renders a fixed orbit around a solid with the stereo renderer (both eyes, one multiview pass)
// and writes the frames as PNG files with their head poses (frames.csv), for checking by eye.
// The solid comes from a mesh file (OBJ, PLY, STL, OFF) or an analytic phantom (--phantom); a
// scene file (.toml) gives its solids as a session draws them, with the structures inside them
// culled where they cannot be seen (--incision: through the procedure's cut).

#include <cstdint>
#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct RenderOptions {
  std::string input;
  std::string phantom;
  std::string output;
  std::uint32_t frames = 90;
  std::uint32_t eye_width = 1024;
  std::uint32_t eye_height = 1024;
  bool per_eye = false;
  bool no_culling = false;
  bool occlusion = false;
  bool no_lod = false;
  bool cpu = false;
  bool validation = false;
  bool json = false;
  bool incision = false;  ///< scene files: cut the first solid along the procedure's cut
};

/// Adds the `render` command; `run` is set when it is the one parsed.
void add_render_command(CLI::App& app, RenderOptions& options, int (*&run)(const RenderOptions&));

int run_render(const RenderOptions& options);

}  // namespace bisturi::cli
