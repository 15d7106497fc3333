#pragma once
// The stereo renderer: Vulkan 1.2, both eyes in one multiview render pass into a two-layer colour
// and depth image, offscreen (a headless device such as Mesa's lavapipe works; a GPU is preferred
// when there is one), frames handed to a FrameSink. Made on an OpenXrSink, it draws on the device
// the OpenXR runtime made and straight into the runtime's two-layer swapchain images: nothing is
// read back (the read-back is only for sinks that want pixels, such as the PNG files).
//
// Per frame, for every solid: frustum culling of the solid's box against both eyes, a level of
// detail picked by projected screen-space error; then the picked levels are the occluders
// (OccluderDepth) against which each level's chunk tree is culled with the frusta (a culled
// chunk costs no draw call; neighbouring visible chunks are drawn as one range); back faces
// are culled by the rasterizer (solids are consistently oriented, counter-clockwise outside) on
// closed solids; a solid with an open boundary (an incision: labelled boundary faces) is drawn
// two-sided, its back faces in the material's interior colour, so a cut reads as tissue.
//
// Streaming: vertex data of the drawn levels go every frame into a buffer owned by the frame in
// flight (no stall on the previous frame); index buffers are rebuilt only when a level's indices
// change (a topology change of the solid) and retired once no frame in flight uses them.

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

#include "bisturi/runtime/render/frame_sink.h"
#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/render/solid_levels.h"
#include "bisturi/scene/dlfl.h"

namespace bisturi::render {

struct Material {
  glm::vec3 colour{0.8f, 0.45f, 0.4f};  ///< linear RGB
  float ambient = 0.35f;
  float diffuse = 0.65f;
  float specular = 0.25f;
  float shininess = 32.0f;
  /// The inner side of the surface (back faces, seen through an incision): a darker, redder
  /// tissue colour, lit without specular highlight (matte), linear RGB.
  glm::vec3 interior_colour{0.42f, 0.06f, 0.05f};
  /// Drawn again, flattened and dark, on the shadow plane (set_shadow_plane): false for what
  /// is the plane itself (a drape) or too small to matter (blood drops).
  bool casts_shadow = true;
};

enum class DevicePreference : std::uint8_t { Any, Gpu, Cpu };

/// The occlusion grid's cells across each eye when occlusion culling is on.
constexpr std::uint32_t kOcclusionCells = 64;

struct RendererOptions {
  HeadsetDescription headset;
  DevicePreference device = DevicePreference::Any;  ///< Any: a GPU when there is one
  /// Enable VK_LAYER_KHRONOS_validation and count its messages (validation_messages()).
  bool validation = false;
  bool frustum_culling = true;
  /// Occlusion culling (OccluderDepth): solids and chunks wholly behind the surfaces the same
  /// frame draws are left out of the eyes' pass (not of the shadows); the grid it tests against
  /// has this many cells across each eye (0: off; kOcclusionCells when on). Off by default: it
  /// costs about 60 ns per occluding triangle and eye on the CPU, more than it saves unless
  /// solids hide a good share of the triangles drawn (a structure inside an organ is already
  /// culled by set_enclosed_by at no such cost).
  std::uint32_t occlusion_cells = 0;
  bool level_of_detail = true;
  /// The coarsest level whose error projects to at most this many pixels is drawn.
  double max_error_px = 1.0;
  /// Frames recorded ahead of the one the device draws. 0: 2 on a GPU, 1 on a CPU device
  /// (lavapipe draws on the same cores that would record the next frame, so a second frame in
  /// flight adds a frame of latency and no throughput).
  std::uint32_t frames_in_flight = 0;
  glm::vec3 clear_colour{0.0f, 0.0f, 0.0f};
  /// An operating lamp at the viewer focused on the solids' centre: the light falls off with
  /// the square of the distance from each eye, relative to the focus (0.3 to 1.4 times), so
  /// nearer tissue is brighter. Off: uniform light, as a plain mesh viewer draws.
  bool field_lamp = false;
  LevelOptions levels;
};

class OpenXrSink;

struct SolidId {
  std::uint32_t index = 0;
};

struct FrameStats {
  std::uint64_t frame = 0;
  std::size_t draw_calls = 0;
  std::size_t triangles_drawn = 0;  ///< submitted (before back-face culling)
  std::size_t solids_culled = 0;
  std::size_t chunks_drawn = 0;
  std::size_t chunks_culled = 0;
  /// Triangles of the levels picked that were not drawn, by the test that left them out: the
  /// eyes' frusta (whole solids and chunks); occlusion, by a closed solid that hides what it
  /// encloses or by the surfaces drawn in front (whole solids and chunks); and an open solid
  /// whose openings (portals) none of the eyes sees the enclosed solid through.
  std::size_t triangles_culled_frustum = 0;
  std::size_t triangles_culled_occlusion = 0;
  std::size_t triangles_culled_portal = 0;
  std::size_t vertex_bytes_uploaded = 0;
  std::size_t index_buffers_rebuilt = 0;
  double cpu_ms = 0.0;   ///< culling, LOD, streaming, recording and submitting on the CPU
  double wait_ms = 0.0;  ///< waiting for this frame's slot: its last frame's GPU work and sink
};

class StereoRenderer {
 public:
  /// Throws NoVulkanDevice when no suitable Vulkan device exists, RenderError otherwise.
  explicit StereoRenderer(const RendererOptions& options);
  /// Draws on `headset`'s device into its swapchain, at its eye size (options.headset's eye size
  /// and validation are replaced by the headset's). `headset` must outlive the renderer.
  StereoRenderer(const RendererOptions& options, OpenXrSink& headset);
  ~StereoRenderer();
  StereoRenderer(const StereoRenderer&) = delete;
  StereoRenderer& operator=(const StereoRenderer&) = delete;

  /// A solid in world millimetres (its positions are used as they are).
  SolidId add_solid(const Dlfl& mesh, const Material& material = {});
  /// An instrument: a mesh in its own frame, drawn at `pose` (model to world, rigid).
  SolidId add_instrument(const Dlfl& mesh, const Material& material, const glm::dmat4& pose);
  /// New positions of a solid (and new topology when its version moved).
  void update_solid(SolidId id, const Dlfl& mesh);
  /// Another mesh for a solid (a new topology, whatever its version says: a mesh imported or
  /// extracted anew starts its own count); its derived levels are dropped.
  void replace_solid(SolidId id, const Dlfl& mesh);
  /// A solid after a cut, its vertices numbered as before (SolidLevels::recut): its coarser
  /// levels are kept.
  void recut_solid(SolidId id, const Dlfl& mesh);
  void rebuild_levels(SolidId id, const Dlfl& mesh);
  void set_pose(SolidId id, const glm::dmat4& pose);
  void set_material(SolidId id, const Material& material);
  void set_visible(SolidId id, bool visible);
  /// A solid's ambient occlusion by vertex (1: the whole sky open; SolidLevels::set_occlusion):
  /// it dims the ambient light and part of the key light there, a soft contact shadow.
  void set_occlusion(SolidId id, std::vector<float> by_vertex);
  /// `inner` lies inside `enclosure`'s closed surface (a lesion in an organ): it is not drawn
  /// while that surface is closed and the eyes are outside its box (it hides all of it), and
  /// once it is open (an incision) only while an eye sees its box through an opening's box
  /// (the incision as a portal, seed section 3.2). A hidden enclosure hides nothing.
  void set_enclosed_by(SolidId inner, SolidId enclosure);
  /// A horizontal surface at z_mm (world millimetres, z up; a drape) takes the shadows of the
  /// solids and instruments under an overhead operating lamp: each is drawn again flattened
  /// onto it, dark, a little above it. NaN: no shadows (the default).
  void set_shadow_plane(double z_mm);
  [[nodiscard]] const SolidLevels& levels(SolidId id) const;
  /// The level drawn for the solid in the last frame (-1: culled or hidden).
  [[nodiscard]] int drawn_level(SolidId id) const;

  /// Frames go here once finished; null: frames are not read back.
  void set_sink(FrameSink* sink);

  /// Records and submits one frame for `head`; the frame reaches the sink once the device is done
  /// with it (during a later call, or flush()).
  FrameStats render(const HeadPose& head);
  /// The same with the eyes a runtime located (their poses and fields of view, not the
  /// headset description's). On a headset: into the swapchain image of the frame that
  /// OpenXrSink::begin_frame began (call OpenXrSink::end_frame after).
  FrameStats render(const HeadPose& head, const std::array<EyePose, 2>& eyes);
  /// Waits for every frame in flight and hands them to the sink.
  void flush();

  [[nodiscard]] const RendererOptions& options() const;
  [[nodiscard]] std::string device_name() const;
  [[nodiscard]] bool device_is_cpu() const;
  /// Frames whose pixels were copied to host memory (for a sink that wanted them).
  [[nodiscard]] std::uint64_t frames_read_back() const;
  /// True when made on an OpenXrSink: frames are drawn into the runtime's images in place.
  [[nodiscard]] bool draws_into_headset() const;
  /// Validation-layer messages (warnings and errors) so far; 0 without validation.
  [[nodiscard]] std::size_t validation_messages() const;
  [[nodiscard]] std::vector<std::string> validation_log() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bisturi::render
