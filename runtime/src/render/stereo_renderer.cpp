#include "bisturi/runtime/render/stereo_renderer.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <deque>
#include <limits>
#include <optional>
#include <span>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/frustum.h"
#include "bisturi/runtime/render/occluder_depth.h"
#include "gpu_buffer.h"
#include "mesh_pipeline.h"
#include "openxr_sink_impl.h"
#include "solid_boundary.h"
#include "stereo_target.h"
#include "vulkan_context.h"

namespace bisturi::render {

namespace {

using Clock = PoseClock;

struct IndexBuffer {
  vk::Buffer buffer;
  std::uint64_t generation = 0;
};

/// A level's edges, for its outline as an occluder (OccluderDepth).
struct LevelEdges {
  TriangleEdges edges;
  std::uint64_t generation = 0;  ///< of the indices they were found in
};

/// A shadow on the drape: very dark green (linear RGB).
constexpr glm::vec3 kShadowColour{0.004f, 0.012f, 0.010f};

struct Solid {
  std::unique_ptr<SolidLevels> levels;
  Material material;
  bool instrument = false;
  glm::dmat4 pose{1.0};
  bool visible = true;
  std::vector<IndexBuffer> index_buffers;  ///< one per level
  std::vector<LevelEdges> edges;           ///< one per level, found when it first occludes
  int drawn_level = -1;
  SolidBoundary boundary;         ///< holed: drawn two-sided
  std::int32_t enclosed_by = -1;  ///< the solid whose closed surface it lies inside
};

/// A box as an eye sees it: its screen rectangle (normalised device coordinates, clamped to the
/// view; the whole view when a corner is behind the eye) and its depth range (clip w).
struct ScreenBox {
  glm::dvec2 lo{std::numeric_limits<double>::infinity()};
  glm::dvec2 hi{-std::numeric_limits<double>::infinity()};
  double near = std::numeric_limits<double>::infinity();
  double far = -std::numeric_limits<double>::infinity();
};

/// False when the box lies wholly beside the view.
bool screen_box(const Aabb& box, const EyeView& eye, ScreenBox& out) {
  out = ScreenBox{};
  glm::dvec2& lo = out.lo;
  glm::dvec2& hi = out.hi;
  bool behind = false;
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? box.hi.x : box.lo.x, (c & 2) ? box.hi.y : box.lo.y,
                       (c & 4) ? box.hi.z : box.lo.z);
    const glm::dvec4 clip = eye.view_projection * glm::dvec4(p, 1.0);
    out.near = std::min(out.near, clip.w);
    out.far = std::max(out.far, clip.w);
    if (clip.w <= 1e-9) {
      behind = true;
      continue;
    }
    const glm::dvec2 ndc(clip.x / clip.w, clip.y / clip.w);
    lo = glm::min(lo, ndc);
    hi = glm::max(hi, ndc);
  }
  if (behind) {
    lo = glm::dvec2(-1.0);
    hi = glm::dvec2(1.0);
    return true;
  }
  lo = glm::max(lo, glm::dvec2(-1.0));
  hi = glm::min(hi, glm::dvec2(1.0));
  return lo.x <= hi.x && lo.y <= hi.y;
}

/// How an enclosed solid can be seen (StereoRenderer::set_enclosed_by).
enum class Enclosure : std::uint8_t { Seen, Occluded, BesidePortals };

struct FrameSlot {
  VkCommandBuffer commands = VK_NULL_HANDLE;
  VkFence fence = VK_NULL_HANDLE;
  VkDescriptorSet descriptors = VK_NULL_HANDLE;
  vk::Buffer uniforms;
  vk::Buffer stream;    ///< vertex data of this frame
  vk::Buffer readback;  ///< both eyes' pixels, when there is a sink
  bool pending = false;
  bool read_back = false;    ///< the frame goes to the sink
  bool copy_pixels = false;  ///< with its pixels
  std::uint64_t frame = 0;
  HeadPose pose;
  Clock::time_point submit_time{};
};

/// One draw of a solid's level: a run of contiguous visible chunks.
struct Range {
  std::uint32_t first_index;
  std::uint32_t index_count;
};

struct PlannedDraw {
  std::size_t solid;
  std::size_t level;
  std::size_t first_range;  ///< in the eyes' pass
  std::size_t range_count;
  std::size_t first_shadow_range;  ///< in the shadows' (occlusion does not cull a shadow)
  std::size_t shadow_range_count;
  VkDeviceSize vertex_offset;
};

/// A solid's level that passed the whole-solid tests, before its chunks are culled.
struct Candidate {
  std::size_t solid;
  std::size_t level;
};

Visibility combine(Visibility a, Visibility b) {
  if (a == Visibility::Inside || b == Visibility::Inside) return Visibility::Inside;
  if (a == Visibility::Intersects || b == Visibility::Intersects) return Visibility::Intersects;
  return Visibility::Outside;
}

glm::mat4 to_float(const glm::dmat4& m) {
  return glm::mat4(m);
}

}  // namespace

struct StereoRenderer::Impl {
  RendererOptions options;
  std::shared_ptr<vk::Context> context;
  /// The headset whose swapchain is drawn into (null: the renderer's own image).
  OpenXrSinkAccess::Impl* xr = nullptr;
  std::uint64_t xr_generation = 0;  ///< of the swapchain the target's framebuffers view
  std::uint64_t frames_read_back = 0;
  std::unique_ptr<vk::StereoTarget> target;
  std::unique_ptr<vk::MeshPipeline> pipeline;
  VkCommandPool pool = VK_NULL_HANDLE;
  VkDescriptorPool descriptor_pool = VK_NULL_HANDLE;
  std::vector<FrameSlot> slots;
  std::vector<Solid> solids;
  double shadow_plane_z_mm = std::numeric_limits<double>::quiet_NaN();
  /// Index buffers replaced while frames in flight may still read them: freed once the frame
  /// counter passes the number stored with them.
  std::deque<std::pair<std::uint64_t, vk::Buffer>> retired;
  FrameSink* sink = nullptr;
  std::uint64_t frame = 0;

  // Per-frame scratch.
  std::vector<Range> ranges;
  std::vector<Range> shadow_ranges;
  std::vector<PlannedDraw> draws;
  std::vector<Candidate> candidates;
  OccluderDepth occluders;

  explicit Impl(const RendererOptions& o) : options(o) {
    if (options.headset.eye_width == 0 || options.headset.eye_height == 0) {
      throw RenderError("the eye resolution must be at least 1 x 1");
    }
    context = std::make_shared<vk::Context>(options.validation, options.device);
    start();
  }

  Impl(const RendererOptions& o, OpenXrSink& headset) : options(o) {
    xr = &OpenXrSinkAccess::of(headset);
    context = xr->context;
    options.headset.eye_width = xr->width;
    options.headset.eye_height = xr->height;
    options.validation = xr->options.validation;
    // The swapchain's images may go (a lost session): the views of them go first.
    xr->before_swapchain_destroyed = [this] {
      vkDeviceWaitIdle(context->device());
      target.reset();
    };
    start();
  }

  void start() {
    if (options.frames_in_flight == 0) options.frames_in_flight = context->is_cpu() ? 1 : 2;
    try {
      create();
    } catch (...) {
      release();
      throw;
    }
  }

  ~Impl() {
    if (xr != nullptr) xr->before_swapchain_destroyed = nullptr;
    release();
  }

  /// The render target: the own image, or the headset's swapchain images as they are now.
  void make_target() {
    if (xr == nullptr) {
      target = std::make_unique<vk::StereoTarget>(*context, options.headset.eye_width,
                                                  options.headset.eye_height);
    } else {
      target.reset();
      options.headset.eye_width = xr->width;
      options.headset.eye_height = xr->height;
      if (!xr->images.empty()) {
        target = std::make_unique<vk::StereoTarget>(*context, xr->width, xr->height,
                                                    xr->view_format, xr->images);
      }
      xr_generation = xr->swapchain_generation;
    }
  }

  void create() {
    const VkDevice device = context->device();
    make_target();
    if (!target) throw RenderError("the OpenXR sink has no swapchain to draw into");
    pipeline = std::make_unique<vk::MeshPipeline>(
        *context, target->render_pass(), options.headset.eye_width, options.headset.eye_height);
    VkCommandPoolCreateInfo pool_info{};
    pool_info.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
    pool_info.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
    pool_info.queueFamilyIndex = context->queue_family();
    vk::check(vkCreateCommandPool(device, &pool_info, nullptr, &pool), "vkCreateCommandPool");

    const std::uint32_t n = options.frames_in_flight;
    VkDescriptorPoolSize size{VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER, n};
    VkDescriptorPoolCreateInfo dp{};
    dp.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_POOL_CREATE_INFO;
    dp.maxSets = n;
    dp.poolSizeCount = 1;
    dp.pPoolSizes = &size;
    vk::check(vkCreateDescriptorPool(device, &dp, nullptr, &descriptor_pool),
              "vkCreateDescriptorPool");

    slots.resize(n);
    for (FrameSlot& slot : slots) {
      VkCommandBufferAllocateInfo alloc{};
      alloc.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
      alloc.commandPool = pool;
      alloc.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
      alloc.commandBufferCount = 1;
      vk::check(vkAllocateCommandBuffers(device, &alloc, &slot.commands),
                "vkAllocateCommandBuffers");
      VkFenceCreateInfo fence{};
      fence.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
      vk::check(vkCreateFence(device, &fence, nullptr, &slot.fence), "vkCreateFence");
      slot.uniforms =
          vk::Buffer(*context, sizeof(vk::EyeUniforms), VK_BUFFER_USAGE_UNIFORM_BUFFER_BIT);
      const VkDescriptorSetLayout layout = pipeline->set_layout();
      VkDescriptorSetAllocateInfo ds{};
      ds.sType = VK_STRUCTURE_TYPE_DESCRIPTOR_SET_ALLOCATE_INFO;
      ds.descriptorPool = descriptor_pool;
      ds.descriptorSetCount = 1;
      ds.pSetLayouts = &layout;
      vk::check(vkAllocateDescriptorSets(device, &ds, &slot.descriptors),
                "vkAllocateDescriptorSets");
      VkDescriptorBufferInfo buffer_info{slot.uniforms.handle(), 0, sizeof(vk::EyeUniforms)};
      VkWriteDescriptorSet write{};
      write.sType = VK_STRUCTURE_TYPE_WRITE_DESCRIPTOR_SET;
      write.dstSet = slot.descriptors;
      write.dstBinding = 0;
      write.descriptorCount = 1;
      write.descriptorType = VK_DESCRIPTOR_TYPE_UNIFORM_BUFFER;
      write.pBufferInfo = &buffer_info;
      vkUpdateDescriptorSets(device, 1, &write, 0, nullptr);
    }
  }

  void release() {
    if (!context) return;
    const VkDevice device = context->device();
    if (device != VK_NULL_HANDLE) vkDeviceWaitIdle(device);
    for (FrameSlot& slot : slots) {
      if (slot.fence != VK_NULL_HANDLE) vkDestroyFence(device, slot.fence, nullptr);
      slot.uniforms.reset();
      slot.stream.reset();
      slot.readback.reset();
    }
    slots.clear();
    solids.clear();
    retired.clear();
    if (descriptor_pool != VK_NULL_HANDLE)
      vkDestroyDescriptorPool(device, descriptor_pool, nullptr);
    if (pool != VK_NULL_HANDLE) vkDestroyCommandPool(device, pool, nullptr);
    descriptor_pool = VK_NULL_HANDLE;
    pool = VK_NULL_HANDLE;
    pipeline.reset();
    target.reset();
    context.reset();
  }

  Solid& solid(SolidId id) {
    if (id.index >= solids.size()) throw RenderError("unknown solid " + std::to_string(id.index));
    return solids[id.index];
  }

  SolidId add(const Dlfl& mesh, const Material& material, bool instrument, const glm::dmat4& pose) {
    Solid s;
    s.levels = std::make_unique<SolidLevels>(mesh, options.levels);
    s.material = material;
    s.instrument = instrument;
    s.pose = pose;
    s.index_buffers.resize(s.levels->level_count());
    s.boundary.rebuild(mesh);
    solids.push_back(std::move(s));
    return SolidId{static_cast<std::uint32_t>(solids.size() - 1)};
  }

  /// Waits for a slot's frame and hands it to the sink.
  void complete(FrameSlot& slot) {
    if (!slot.pending) return;
    vk::check(vkWaitForFences(context->device(), 1, &slot.fence, VK_TRUE,
                              std::numeric_limits<std::uint64_t>::max()),
              "vkWaitForFences");
    vk::check(vkResetFences(context->device(), 1, &slot.fence), "vkResetFences");
    slot.pending = false;
    if (slot.read_back && sink != nullptr) {
      StereoFrame out;
      out.index = slot.frame;
      out.eye_width = options.headset.eye_width;
      out.eye_height = options.headset.eye_height;
      if (slot.copy_pixels) {
        slot.readback.invalidate();
        out.pixels = {reinterpret_cast<const std::uint8_t*>(slot.readback.data()),
                      std::size_t{out.eye_width} * out.eye_height * 4 * 2};
      }
      out.pose = slot.pose;
      out.submit_time = slot.submit_time;
      out.ready_time = Clock::now();
      sink->consume(out);
    }
  }

  void flush() { deliver(true); }

  /// Hands the frames the device has finished to the sink, oldest first (frames go to the sink in
  /// order): all of them when `wait`, else those whose fence is already signalled, so a finished
  /// frame reaches the sink (and the headset) now rather than when its slot comes round again.
  void deliver(bool wait) {
    // Slots are used in turn (frame % count): the pending ones are among the last `count`
    // frames, visited here oldest first.
    const std::uint64_t count = slots.size();
    for (std::uint64_t f = frame > count ? frame - count : 0; f < frame; ++f) {
      FrameSlot& s = slots[f % count];
      if (!s.pending || s.frame != f) continue;
      if (!wait && vkGetFenceStatus(context->device(), s.fence) != VK_SUCCESS) break;
      complete(s);
    }
  }

  /// Whether `inner` (its box `bounds`) can be seen past the solid that encloses it.
  Enclosure enclosure_test(const Solid& inner, const Aabb& bounds,
                           const std::array<EyeView, 2>& eyes) const {
    const Solid& outer = solids[static_cast<std::size_t>(inner.enclosed_by)];
    if (!outer.visible) return Enclosure::Seen;
    const Aabb& hull = outer.levels->bounds();
    for (const EyeView& eye : eyes) {
      const glm::dvec3& e = eye.position_mm;
      if (glm::all(glm::greaterThanEqual(e, hull.lo)) && glm::all(glm::lessThanEqual(e, hull.hi)))
        return Enclosure::Seen;  // an eye inside the enclosure's box: no claim
    }
    if (!outer.boundary.open()) return Enclosure::Occluded;
    // Seen through a portal: their rectangles overlap, and some of the solid lies beyond the
    // portal's nearest point (an opening behind the solid shows it to no eye in front).
    for (const EyeView& eye : eyes) {
      ScreenBox in;
      if (!screen_box(bounds, eye, in)) continue;
      for (const Aabb& portal : outer.boundary.portals()) {
        ScreenBox p;
        if (!screen_box(portal, eye, p)) continue;
        if (p.lo.x <= in.hi.x && in.lo.x <= p.hi.x && p.lo.y <= in.hi.y && in.lo.y <= p.hi.y &&
            in.far > p.near)
          return Enclosure::Seen;
      }
    }
    return Enclosure::BesidePortals;
  }

  /// Chunks of `level` visible in either eye, as merged index ranges: into `ranges` those the
  /// frusta and the occluders leave, into `shadow_ranges` (when `shadows`) those the frusta
  /// leave.
  void cull_chunks(const ChunkTree& tree, const std::array<Frustum, 2>& frusta,
                   const glm::dmat4* pose, bool shadows, FrameStats& stats) {
    if (tree.nodes.empty()) return;
    const auto append = [&](std::vector<Range>& out, std::uint32_t first_chunk,
                            std::uint32_t count) {
      for (std::uint32_t c = first_chunk; c < first_chunk + count; ++c) {
        const Chunk& chunk = tree.chunks[c];
        if (!out.empty() && out.back().first_index + out.back().index_count == chunk.first_index) {
          out.back().index_count += chunk.index_count;
        } else {
          out.push_back({chunk.first_index, chunk.index_count});
        }
      }
    };
    const auto culled = [&](const ChunkNode& node, std::size_t& triangles) {
      stats.chunks_culled += node.chunk_count;
      for (std::uint32_t c = node.first_chunk; c < node.first_chunk + node.chunk_count; ++c)
        triangles += tree.chunks[c].index_count / 3;
    };
    const bool occlusion = options.occlusion_cells > 0;
    // Nodes to visit, with whether the frusta hold them whole (their children need no test).
    std::array<std::pair<std::int32_t, bool>, 64> stack{};
    std::size_t top = 0;
    stack[top++] = {0, !options.frustum_culling};
    while (top > 0) {
      const auto [index, inside] = stack[--top];
      const ChunkNode& node = tree.nodes[static_cast<std::size_t>(index)];
      const Aabb box = pose != nullptr ? node.bounds.transformed(*pose) : node.bounds;
      const Visibility v =
          inside ? Visibility::Inside : combine(frusta[0].classify(box), frusta[1].classify(box));
      if (v == Visibility::Outside) {
        culled(node, stats.triangles_culled_frustum);
      } else if (occlusion && occluders.hides(box)) {
        culled(node, stats.triangles_culled_occlusion);
        if (shadows) append(shadow_ranges, node.first_chunk, node.chunk_count);
      } else if ((v == Visibility::Inside && !occlusion) || node.left < 0 ||
                 top + 2 > stack.size()) {
        append(ranges, node.first_chunk, node.chunk_count);
        if (shadows) append(shadow_ranges, node.first_chunk, node.chunk_count);
        stats.chunks_drawn += node.chunk_count;
      } else {
        // Left first: ranges come out in index order.
        const bool whole = v == Visibility::Inside;
        stack[top++] = {node.right, whole};
        stack[top++] = {node.left, whole};
      }
    }
  }

  /// A level's edges, found again when its indices changed.
  const TriangleEdges& edges_of(Solid& s, std::size_t level_index) {
    if (s.edges.size() < s.levels->level_count()) s.edges.resize(s.levels->level_count());
    const SolidLevel& level = s.levels->level(level_index);
    LevelEdges& cached = s.edges[level_index];
    if (cached.generation != level.index_generation || cached.generation == 0) {
      cached.edges = triangle_edges(level.indices, level.vertices.size() / 6);
      cached.generation = level.index_generation;
    }
    return cached.edges;
  }

  /// Starts the frame's occluders: every solid (not the instruments) at the level planned.
  void gather_occluders(const std::array<EyeView, 2>& eyes) {
    if (options.occlusion_cells == 0) return;
    const std::uint32_t columns = options.occlusion_cells;
    const auto rows = static_cast<std::uint32_t>(
        std::max(1.0, std::round(static_cast<double>(columns) * options.headset.eye_height /
                                 options.headset.eye_width)));
    occluders.begin({eyes[0].view_projection, eyes[1].view_projection},
                    {eyes[0].position_mm, eyes[1].position_mm}, columns, rows);
    for (const Candidate& c : candidates) {
      Solid& s = solids[c.solid];
      if (s.instrument) continue;
      const SolidLevel& level = s.levels->level(c.level);
      occluders.add(level.vertices, 6, level.indices, edges_of(s, c.level), s.boundary.holed());
    }
  }

  /// The planned draws again, flattened onto the shadow plane under an overhead lamp (straight
  /// down: the shadow is each solid's footprint), dark and unlit, 0.3 mm above the plane so the
  /// plane does not hide them. A thousandth of the height is kept so the normals stay finite.
  void record_shadows(VkCommandBuffer cmd, const FrameSlot& slot, VkPipeline& bound,
                      FrameStats& stats) {
    if (!std::isfinite(shadow_plane_z_mm)) return;
    constexpr double kKeep = 1e-3, kLift_mm = 0.3;
    glm::dmat4 flatten(1.0);
    flatten[2][2] = kKeep;
    flatten[3][2] = (1.0 - kKeep) * shadow_plane_z_mm + kLift_mm;
    for (const PlannedDraw& d : draws) {
      const Solid& s = solids[d.solid];
      if (!s.material.casts_shadow || d.shadow_range_count == 0) continue;
      vk::DrawConstants constants;
      constants.model = to_float(flatten * (s.instrument ? s.pose : glm::dmat4(1.0)));
      constants.colour = glm::vec4(kShadowColour, 1.0f);
      constants.material = {1.0f, 0.0f, 0.0f, 1.0f};
      constants.interior = glm::vec4(kShadowColour, 0.0f);
      record_draw(cmd, slot, d, constants,
                  {shadow_ranges.data() + d.first_shadow_range, d.shadow_range_count}, bound,
                  stats);
    }
  }

  /// One planned draw with `constants`: its pipeline (two-sided for a holed solid), its
  /// streamed vertices and index ranges.
  void record_draw(VkCommandBuffer cmd, const FrameSlot& slot, const PlannedDraw& d,
                   const vk::DrawConstants& constants, std::span<const Range> drawn,
                   VkPipeline& bound, FrameStats& stats) {
    const Solid& s = solids[d.solid];
    const VkPipeline wanted = s.boundary.holed() ? pipeline->two_sided() : pipeline->pipeline();
    if (wanted != bound) {
      vkCmdBindPipeline(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, wanted);
      bound = wanted;
    }
    vkCmdPushConstants(cmd, pipeline->layout(),
                       VK_SHADER_STAGE_VERTEX_BIT | VK_SHADER_STAGE_FRAGMENT_BIT, 0,
                       sizeof(constants), &constants);
    const VkBuffer vertex_buffer = slot.stream.handle();
    vkCmdBindVertexBuffers(cmd, 0, 1, &vertex_buffer, &d.vertex_offset);
    vkCmdBindIndexBuffer(cmd, s.index_buffers[d.level].buffer.handle(), 0, VK_INDEX_TYPE_UINT32);
    for (const Range& r : drawn) {
      vkCmdDrawIndexed(cmd, r.index_count, 1, r.first_index, 0, 0);
      ++stats.draw_calls;
      stats.triangles_drawn += r.index_count / 3;
    }
  }

  /// The coarsest level whose error projects to at most max_error_px in either eye.
  std::size_t pick_level(const SolidLevels& levels, const Aabb& world_bounds,
                         const std::array<EyeView, 2>& eyes) const {
    if (!options.level_of_detail) return levels.source_level();
    double distance = std::numeric_limits<double>::infinity();
    double pixels_per_tangent = 0.0;
    for (const EyeView& eye : eyes) {
      distance = std::min(distance, distance_to(world_bounds, eye.position_mm));
      const double span = std::tan(static_cast<double>(eye.fov.angle_up)) -
                          std::tan(static_cast<double>(eye.fov.angle_down));
      pixels_per_tangent =
          std::max(pixels_per_tangent, static_cast<double>(options.headset.eye_height) / span);
    }
    std::size_t chosen = 0;
    for (std::size_t i = 0; i < levels.level_count(); ++i) {
      if (projected_error_px(levels.level(i).error_mm, distance, pixels_per_tangent) <=
          options.max_error_px) {
        chosen = i;
      } else {
        break;
      }
    }
    return chosen;
  }

  FrameStats render(const HeadPose& head, const std::array<EyeView, 2>& eyes) {
    const auto wait_start = Clock::now();
    FrameStats stats;
    stats.frame = frame;
    FrameSlot& slot = slots[frame % slots.size()];
    complete(slot);
    std::uint32_t image = 0;
    if (xr != nullptr) {
      if (!xr->image_acquired) {
        throw RenderError(
            "a headset frame was rendered without a swapchain image (call "
            "OpenXrSink::begin_frame first, and render only when it says so)");
      }
      if (xr->swapchain_generation != xr_generation || !target) {
        // A new swapchain (the session was made again): new views of its images. Its size and
        // format are those of the old one, so the pipeline stays.
        vkDeviceWaitIdle(context->device());
        make_target();
        if (!target) throw RenderError("the OpenXR sink has no swapchain to draw into");
      }
      image = xr->acquired_index;
    }
    // The slot's last frame (GPU work and the sink) is waited for apart: on a GPU it is most of
    // a frame, and the CPU's own share would hide in it.
    const auto cpu_start = Clock::now();
    stats.wait_ms = std::chrono::duration<double, std::milli>(cpu_start - wait_start).count();
    while (!retired.empty() && retired.front().first <= frame)
      retired.pop_front();

    const std::array<Frustum, 2> frusta{Frustum::from_view_projection(eyes[0].view_projection),
                                        Frustum::from_view_projection(eyes[1].view_projection)};
    vk::EyeUniforms uniforms{};
    for (int e = 0; e < 2; ++e) {
      uniforms.view_projection[e] = to_float(eyes[static_cast<std::size_t>(e)].view_projection);
      uniforms.eye_position[e] =
          glm::vec4(glm::vec3(eyes[static_cast<std::size_t>(e)].position_mm), 1.0f);
    }
    // A key light above and behind the viewer's head.
    const glm::dmat3 head_rotation = glm::mat3_cast(glm::normalize(head.orientation));
    uniforms.light_direction =
        glm::vec4(glm::vec3(glm::normalize(head_rotation * glm::dvec3(0.3, 0.8, 0.6))), 0.0f);
    if (options.field_lamp) {
      Aabb field;
      for (const Solid& s : solids) {
        if (s.visible && !s.instrument) field.extend(s.levels->bounds());
      }
      if (!field.empty()) uniforms.lamp = glm::vec4(glm::vec3(0.5 * (field.lo + field.hi)), 1.0f);
    }
    std::memcpy(slot.uniforms.data(), &uniforms, sizeof(uniforms));

    // Plan: cull solids, pick levels; the occluders from those levels; cull chunks; count the
    // vertex bytes to stream.
    ranges.clear();
    shadow_ranges.clear();
    draws.clear();
    candidates.clear();
    for (std::size_t i = 0; i < solids.size(); ++i) {
      Solid& s = solids[i];
      s.drawn_level = -1;
      if (!s.visible) continue;
      const Aabb bounds =
          s.instrument ? s.levels->bounds().transformed(s.pose) : s.levels->bounds();
      const std::size_t level_index = pick_level(*s.levels, bounds, eyes);
      const std::size_t triangles = s.levels->level(level_index).triangle_count();
      if (options.frustum_culling &&
          combine(frusta[0].classify(bounds), frusta[1].classify(bounds)) == Visibility::Outside) {
        ++stats.solids_culled;
        stats.triangles_culled_frustum += triangles;
        continue;
      }
      if (s.enclosed_by >= 0) {
        const Enclosure seen = enclosure_test(s, bounds, eyes);
        if (seen != Enclosure::Seen) {
          ++stats.solids_culled;
          (seen == Enclosure::Occluded ? stats.triangles_culled_occlusion
                                       : stats.triangles_culled_portal) += triangles;
          continue;
        }
      }
      s.levels->refresh(level_index);
      candidates.push_back({i, level_index});
    }
    gather_occluders(eyes);
    VkDeviceSize stream_bytes = 0;
    const bool shadow_plane = std::isfinite(shadow_plane_z_mm);
    for (const Candidate& c : candidates) {
      Solid& s = solids[c.solid];
      const SolidLevel& level = s.levels->level(c.level);
      const std::size_t first_range = ranges.size();
      const std::size_t first_shadow_range = shadow_ranges.size();
      cull_chunks(level.tree, frusta, s.instrument ? &s.pose : nullptr,
                  shadow_plane && s.material.casts_shadow, stats);
      const std::size_t range_count = ranges.size() - first_range;
      const std::size_t shadow_range_count = shadow_ranges.size() - first_shadow_range;
      if (range_count == 0) ++stats.solids_culled;
      if (range_count == 0 && shadow_range_count == 0) continue;
      if (range_count > 0) s.drawn_level = static_cast<int>(c.level);
      draws.push_back({c.solid, c.level, first_range, range_count, first_shadow_range,
                       shadow_range_count, stream_bytes});
      stream_bytes += (level.vertices.size() * sizeof(float) + 255) & ~VkDeviceSize{255};
    }

    // Stream the vertices into this frame's buffer (its previous frame is done: no stall).
    if (stream_bytes > slot.stream.size()) {
      slot.stream =
          vk::Buffer(*context, std::max<VkDeviceSize>(stream_bytes + stream_bytes / 2, 1 << 16),
                     VK_BUFFER_USAGE_VERTEX_BUFFER_BIT);
    }
    for (const PlannedDraw& d : draws) {
      Solid& s = solids[d.solid];
      const SolidLevel& level = s.levels->level(d.level);
      std::memcpy(slot.stream.data() + d.vertex_offset, level.vertices.data(),
                  level.vertices.size() * sizeof(float));
      stats.vertex_bytes_uploaded += level.vertices.size() * sizeof(float);
      IndexBuffer& ib = s.index_buffers[d.level];
      if (ib.generation != level.index_generation || ib.buffer.handle() == VK_NULL_HANDLE) {
        if (ib.buffer.handle() != VK_NULL_HANDLE) {
          retired.emplace_back(frame + slots.size(), std::move(ib.buffer));
        }
        ib.buffer = vk::Buffer(*context, std::max<std::size_t>(level.indices.size(), 1) * 4,
                               VK_BUFFER_USAGE_INDEX_BUFFER_BIT);
        std::memcpy(ib.buffer.data(), level.indices.data(), level.indices.size() * 4);
        ib.generation = level.index_generation;
        ++stats.index_buffers_rebuilt;
      }
    }

    // Record.
    const VkCommandBuffer cmd = slot.commands;
    vk::check(vkResetCommandBuffer(cmd, 0), "vkResetCommandBuffer");
    VkCommandBufferBeginInfo begin{};
    begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
    begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
    vk::check(vkBeginCommandBuffer(cmd, &begin), "vkBeginCommandBuffer");
    std::array<VkClearValue, 2> clear{};
    clear[0].color = {
        {options.clear_colour.r, options.clear_colour.g, options.clear_colour.b, 1.0f}};
    clear[1].depthStencil = {1.0f, 0};
    VkRenderPassBeginInfo pass{};
    pass.sType = VK_STRUCTURE_TYPE_RENDER_PASS_BEGIN_INFO;
    pass.renderPass = target->render_pass();
    pass.framebuffer = target->framebuffer(image);
    pass.renderArea = {{0, 0}, {options.headset.eye_width, options.headset.eye_height}};
    pass.clearValueCount = static_cast<std::uint32_t>(clear.size());
    pass.pClearValues = clear.data();
    vkCmdBeginRenderPass(cmd, &pass, VK_SUBPASS_CONTENTS_INLINE);
    VkPipeline bound = VK_NULL_HANDLE;
    vkCmdBindDescriptorSets(cmd, VK_PIPELINE_BIND_POINT_GRAPHICS, pipeline->layout(), 0, 1,
                            &slot.descriptors, 0, nullptr);
    for (const PlannedDraw& d : draws) {
      const Solid& s = solids[d.solid];
      if (d.range_count == 0) continue;  // hidden, drawn only in the shadows
      vk::DrawConstants constants;
      constants.model = to_float(s.instrument ? s.pose : glm::dmat4(1.0));
      constants.colour = glm::vec4(s.material.colour, 1.0f);
      constants.material = {s.material.ambient, s.material.diffuse, s.material.specular,
                            s.material.shininess};
      constants.interior = glm::vec4(s.material.interior_colour, 0.0f);
      record_draw(cmd, slot, d, constants, {ranges.data() + d.first_range, d.range_count}, bound,
                  stats);
    }
    record_shadows(cmd, slot, bound, stats);
    vkCmdEndRenderPass(cmd);

    slot.read_back = sink != nullptr;
    // A runtime's image is never copied out: it stays on the device for the compositor.
    slot.copy_pixels = slot.read_back && !target->external() && sink->wants_pixels(frame);
    if (slot.copy_pixels) ++frames_read_back;
    if (slot.copy_pixels) {
      const VkDeviceSize bytes =
          VkDeviceSize{options.headset.eye_width} * options.headset.eye_height * 4 * 2;
      if (slot.readback.size() < bytes) {
        slot.readback =
            vk::Buffer(*context, bytes, VK_BUFFER_USAGE_TRANSFER_DST_BIT, vk::HostAccess::Read);
      }
      VkBufferImageCopy copy{};
      copy.imageSubresource = {VK_IMAGE_ASPECT_COLOR_BIT, 0, 0, 2};
      copy.imageExtent = {options.headset.eye_width, options.headset.eye_height, 1};
      vkCmdCopyImageToBuffer(cmd, target->colour_image(), VK_IMAGE_LAYOUT_TRANSFER_SRC_OPTIMAL,
                             slot.readback.handle(), 1, &copy);
      VkMemoryBarrier to_host{};
      to_host.sType = VK_STRUCTURE_TYPE_MEMORY_BARRIER;
      to_host.srcAccessMask = VK_ACCESS_TRANSFER_WRITE_BIT;
      to_host.dstAccessMask = VK_ACCESS_HOST_READ_BIT;
      vkCmdPipelineBarrier(cmd, VK_PIPELINE_STAGE_TRANSFER_BIT, VK_PIPELINE_STAGE_HOST_BIT, 0, 1,
                           &to_host, 0, nullptr, 0, nullptr);
    }
    vk::check(vkEndCommandBuffer(cmd), "vkEndCommandBuffer");

    VkSubmitInfo submit{};
    submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
    submit.commandBufferCount = 1;
    submit.pCommandBuffers = &cmd;
    vk::check(vkQueueSubmit(context->queue(), 1, &submit, slot.fence), "vkQueueSubmit");
    slot.pending = true;
    slot.frame = frame;
    slot.pose = head;
    slot.submit_time = Clock::now();
    stats.cpu_ms = std::chrono::duration<double, std::milli>(slot.submit_time - cpu_start).count();
    ++frame;
    // With one frame in flight nothing is recorded meanwhile: wait for it here.
    deliver(slots.size() == 1);
    return stats;
  }
};

StereoRenderer::StereoRenderer(const RendererOptions& options)
    : impl_(std::make_unique<Impl>(options)) {}

StereoRenderer::StereoRenderer(const RendererOptions& options, OpenXrSink& headset)
    : impl_(std::make_unique<Impl>(options, headset)) {}

StereoRenderer::~StereoRenderer() = default;

SolidId StereoRenderer::add_solid(const Dlfl& mesh, const Material& material) {
  return impl_->add(mesh, material, false, glm::dmat4(1.0));
}

SolidId StereoRenderer::add_instrument(const Dlfl& mesh, const Material& material,
                                       const glm::dmat4& pose) {
  return impl_->add(mesh, material, true, pose);
}

void StereoRenderer::update_solid(SolidId id, const Dlfl& mesh) {
  Solid& s = impl_->solid(id);
  s.levels->update(mesh);
  s.index_buffers.resize(s.levels->level_count());
  if (mesh.topology_version() != s.boundary.topology_version()) {
    s.boundary.rebuild(mesh);
  } else {
    s.boundary.refit(mesh);
  }
}

void StereoRenderer::replace_solid(SolidId id, const Dlfl& mesh) {
  Solid& s = impl_->solid(id);
  s.levels->replace(mesh);
  s.index_buffers.resize(s.levels->level_count());
  s.boundary.rebuild(mesh);
}

void StereoRenderer::recut_solid(SolidId id, const Dlfl& mesh) {
  Solid& s = impl_->solid(id);
  s.levels->recut(mesh);
  s.index_buffers.resize(s.levels->level_count());
  s.boundary.rebuild(mesh);
}

void StereoRenderer::rebuild_levels(SolidId id, const Dlfl& mesh) {
  Solid& s = impl_->solid(id);
  s.levels->rebuild_derived_levels(mesh);
  s.index_buffers.resize(s.levels->level_count());
  s.boundary.rebuild(mesh);
}

void StereoRenderer::set_pose(SolidId id, const glm::dmat4& pose) {
  impl_->solid(id).pose = pose;
}
void StereoRenderer::set_material(SolidId id, const Material& material) {
  impl_->solid(id).material = material;
}
void StereoRenderer::set_visible(SolidId id, bool visible) {
  impl_->solid(id).visible = visible;
}
void StereoRenderer::set_occlusion(SolidId id, std::vector<float> by_vertex) {
  impl_->solid(id).levels->set_occlusion(std::move(by_vertex));
}
void StereoRenderer::set_enclosed_by(SolidId inner, SolidId enclosure) {
  impl_->solid(inner).enclosed_by = static_cast<std::int32_t>(enclosure.index);
}
void StereoRenderer::set_shadow_plane(double z_mm) {
  impl_->shadow_plane_z_mm = z_mm;
}
const SolidLevels& StereoRenderer::levels(SolidId id) const {
  return *impl_->solid(id).levels;
}
int StereoRenderer::drawn_level(SolidId id) const {
  return impl_->solid(id).drawn_level;
}
void StereoRenderer::set_sink(FrameSink* sink) {
  impl_->flush();
  impl_->sink = sink;
}
FrameStats StereoRenderer::render(const HeadPose& head) {
  return impl_->render(head, eye_views(impl_->options.headset, head));
}
FrameStats StereoRenderer::render(const HeadPose& head, const std::array<EyePose, 2>& eyes) {
  return impl_->render(head, eye_views(impl_->options.headset, eyes));
}
std::uint64_t StereoRenderer::frames_read_back() const {
  return impl_->frames_read_back;
}
bool StereoRenderer::draws_into_headset() const {
  return impl_->xr != nullptr;
}
void StereoRenderer::flush() {
  impl_->flush();
}
const RendererOptions& StereoRenderer::options() const {
  return impl_->options;
}
std::string StereoRenderer::device_name() const {
  return impl_->context->properties().deviceName;
}
bool StereoRenderer::device_is_cpu() const {
  return impl_->context->is_cpu();
}
std::size_t StereoRenderer::validation_messages() const {
  return impl_->context->validation_messages();
}
std::vector<std::string> StereoRenderer::validation_log() const {
  return impl_->context->validation_log();
}

}  // namespace bisturi::render
