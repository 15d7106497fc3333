// The session's render thread (see render_loop.h).

#include "render_loop.h"

#include <chrono>
#include <thread>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/instrument_mesh.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/scene/polygon_import.h"

namespace bisturi::runtime {

namespace {

using devices::Nanoseconds;

double ms(Nanoseconds d) {
  return static_cast<double>(d.count()) * 1e-6;
}

/// The render thread's copy of a solid: its DLFL and where each body vertex slot went.
struct RenderSolid {
  Dlfl mesh;
  std::uint64_t version = 0;
  std::vector<std::pair<std::uint32_t, VertexId>> slot_to_vertex;

  void rebuild(const Topology& t) {
    ImportResult r = import_polygons(t.polygons, true);
    mesh = std::move(r.mesh);
    version = t.version;
    slot_to_vertex.clear();
    for (std::size_t k = 0; k < t.slot_of_position.size(); ++k)
      slot_to_vertex.emplace_back(t.slot_of_position[k], r.vertex_of_input[k]);
  }
  void set_positions(const std::vector<glm::dvec3>& positions_mm) {
    for (const auto& [slot, v] : slot_to_vertex)
      if (slot < positions_mm.size() && v.idx < mesh.vertex_capacity())
        mesh.positions()[v.idx] = positions_mm[slot];
  }
};


/// Frames pass through here on their way to the real sink: motion-to-photon and action-to-response
/// are measured at the moment the image is finished.
class MeasuringSink final : public render::FrameSink {
 public:
  MeasuringSink(render::FrameSink* inner, SessionReport& report,
                std::vector<double>& event_response_ms, std::vector<Nanoseconds>& event_times)
      : inner_(inner), report_(report), response_(event_response_ms), event_times_(event_times) {}

  /// Events first shown by frame `frame`. The frame may have reached the sink already (with one
  /// frame in flight the renderer hands it over before render() returns): then it counts now.
  void shows(std::uint64_t frame, std::uint64_t event) {
    if (any_ready_ && frame <= last_frame_) {
      respond(event, last_ready_);
    } else {
      pending_.push_back({frame, event});
    }
  }

  [[nodiscard]] bool wants_pixels(std::uint64_t index) const override {
    return inner_ != nullptr && inner_->wants_pixels(index);
  }
  void consume(const render::StereoFrame& frame) override {
    if (inner_ != nullptr) inner_->consume(frame);
    ++consumed_;
    if (frame.pose.sample_time.time_since_epoch().count() == 0) return;  // no pose yet
    report_.motion_to_photon_ms.record(
        std::chrono::duration<double, std::milli>(frame.ready_time - frame.pose.sample_time)
            .count());
    const Nanoseconds ready =
        std::chrono::duration_cast<Nanoseconds>(frame.ready_time.time_since_epoch());
    any_ready_ = true;
    last_frame_ = frame.index;
    last_ready_ = ready;
    std::size_t kept = 0;
    for (const auto& [f, e] : pending_) {
      if (f <= frame.index) {
        respond(e, ready);
      } else {
        pending_[kept++] = {f, e};
      }
    }
    pending_.resize(kept);
  }
  [[nodiscard]] std::uint64_t consumed() const { return consumed_; }

 private:
  void respond(std::uint64_t event, Nanoseconds ready) {
    const double latency = ms(ready - event_times_[event]);
    response_[event] = latency;
    report_.action_to_response_ms.record(latency);
  }

  render::FrameSink* inner_;
  SessionReport& report_;
  std::vector<double>& response_;
  std::vector<Nanoseconds>& event_times_;
  std::vector<std::pair<std::uint64_t, std::uint64_t>> pending_;
  std::uint64_t consumed_ = 0;
  bool any_ready_ = false;
  std::uint64_t last_frame_ = 0;
  Nanoseconds last_ready_{0};
};

glm::dmat4 instrument_pose(const glm::dvec3& from_mm, const glm::dvec3& to_mm) {
  // The capsule runs along +z from the origin: rotate +z onto (to - from), then translate.
  const glm::dvec3 axis = to_mm - from_mm;
  const double len = glm::length(axis);
  glm::dmat4 m = glm::translate(glm::dmat4(1.0), from_mm);
  if (len > 1e-9) {
    const glm::dquat q = glm::rotation(glm::dvec3(0, 0, 1), axis / len);
    m = m * glm::mat4_cast(q);
  }
  return m;
}

}  // namespace

void run_render_loop(const RenderLoopContext& c) {
  const SceneDescription& scene = c.scene;
  const SessionOptions& options = c.options;
  SessionReport& report = c.report;
  const Snapshot& initial = c.initial;
  TripleBuffer<Snapshot>& handoff = c.snapshots;
  TripleBuffer<render::HeadPose>& head_handoff = c.head_poses;
  const std::atomic<bool>& stop = c.stop;
  std::atomic<bool>& render_ready = c.ready;
  std::atomic<std::uint64_t>& frames = c.frames;
  std::vector<double>& event_response = c.event_response_ms;
  std::vector<Nanoseconds>& event_times = c.event_times;
  const double display_period_ms = 1000.0 / report.display_hz;
  render::RendererOptions ro;
  ro.device = options.render_device;
  ro.headset.ipd_mm = scene.headset.ipd_mm;
  ro.headset.eye_width = report.eye_width;
  ro.headset.eye_height = report.eye_height;
  constexpr double kRad = 3.14159265358979323846 / 180.0;
  for (render::EyeFov& f : ro.headset.fov) {
    f.angle_left = static_cast<float>(-scene.headset.fov_deg[0] * kRad);
    f.angle_right = static_cast<float>(scene.headset.fov_deg[1] * kRad);
    f.angle_up = static_cast<float>(scene.headset.fov_deg[2] * kRad);
    f.angle_down = static_cast<float>(-scene.headset.fov_deg[3] * kRad);
  }
  render::StereoRenderer renderer(ro);
  report.render_device = renderer.device_name();
  report.render_device_is_cpu = renderer.device_is_cpu();
  std::unique_ptr<render::FrameSink> sink;
  render::PngSink* png = nullptr;
  if (options.openxr) {
    try {
      sink = std::make_unique<render::OpenXrSink>(
          render::OpenXrSinkOptions{.rendered = ro.headset});  // views carry its fov and IPD
      report.sink = "openxr";
    } catch (const render::XrUnavailable& e) {
      report.sink_note =
          std::string("OpenXR unavailable (") + e.what() + "): frames go to the PNG sink";
    }
  }
  if (!sink && !options.frames_dir.empty()) {
    auto p = std::make_unique<render::PngSink>(
        options.frames_dir,
        render::PngSinkOptions{render::PngLayout::SideBySide, options.image_every});
    png = p.get();
    sink = std::move(p);
    report.sink = "png";
  }
  if (!sink) report.sink = "none";
  const bool runtime_paces = report.sink == "openxr";
  MeasuringSink measuring(sink.get(), report, event_response, event_times);
  renderer.set_sink(&measuring);

  std::vector<RenderSolid> meshes(initial.solids.size());
  std::vector<render::SolidId> ids;
  for (std::size_t b = 0; b < initial.solids.size(); ++b) {
    meshes[b].rebuild(*initial.solids[b].topology);
    meshes[b].set_positions(initial.solids[b].positions_mm);
    const auto& rgb = scene.solids[b].material.colour;
    render::Material m;
    m.colour = glm::vec3(static_cast<float>(rgb[0]), static_cast<float>(rgb[1]),
                         static_cast<float>(rgb[2]));
    ids.push_back(renderer.add_solid(meshes[b].mesh, m));
  }
  double probe_radius = 1.5, probe_length = 60.0;
  for (const InstrumentDescription& in : scene.instruments) {
    if (in.kind == InstrumentDescription::Kind::Probe) {
      probe_radius = in.radius_mm;
      probe_length = in.length_mm;
    }
  }
  render::Material steel;
  steel.colour = {0.75f, 0.78f, 0.82f};
  steel.specular = 0.8f;
  const render::SolidId probe_id = renderer.add_instrument(
      render::capsule_solid(probe_radius, probe_length), steel, glm::dmat4(1.0));
  render::Material blade_material = steel;
  blade_material.colour = {0.95f, 0.95f, 1.0f};
  const render::SolidId blade_id =
      renderer.add_instrument(render::capsule_solid(0.4, 1.0), blade_material, glm::dmat4(1.0));
  renderer.set_visible(blade_id, false);
  render_ready.store(true);

  std::uint64_t seen_events = 0;
  const auto period = std::chrono::duration<double, std::milli>(display_period_ms);
  auto next = std::chrono::steady_clock::now();
  auto previous = next;
  bool first = true;
  // The first frame waits for the first snapshot (the haptic thread's start).
  while (!stop.load(std::memory_order_relaxed) && !handoff.take())
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  while (!stop.load(std::memory_order_relaxed)) {
    const auto begin = std::chrono::steady_clock::now();
    handoff.take();
    const Snapshot& s = handoff.front();
    for (std::size_t b = 0; b < s.solids.size(); ++b) {
      const SolidState& st = s.solids[b];
      if (st.topology->version != meshes[b].version) meshes[b].rebuild(*st.topology);
      meshes[b].set_positions(st.positions_mm);
      renderer.update_solid(ids[b], meshes[b].mesh);
    }
    // The probe's shaft rises from the tip along the hand; the blade shows while it cuts.
    const glm::dvec3 along = s.blade_to_mm - s.tip_mm;
    const double along_len = glm::length(along);
    const glm::dvec3 dir = along_len > 1e-9 ? along / along_len : glm::dvec3(0, 0, 1);
    renderer.set_pose(probe_id, instrument_pose(s.tip_mm, s.tip_mm + dir * probe_length));
    renderer.set_visible(blade_id, s.cutting);
    if (s.cutting) {
      glm::dmat4 m = instrument_pose(s.tip_mm, s.blade_to_mm);
      m = m * glm::scale(glm::dmat4(1.0),
                         glm::dvec3(1.0, 1.0, glm::length(s.blade_to_mm - s.tip_mm)));
      renderer.set_pose(blade_id, m);
    }
    head_handoff.take();
    const render::HeadPose pose = head_handoff.front();
    const render::FrameStats stats = renderer.render(pose);
    for (; seen_events < s.event_count; ++seen_events) {
      if (s.event_count - seen_events <= s.recent.size())
        measuring.shows(stats.frame, seen_events);
    }
    const auto end = std::chrono::steady_clock::now();
    report.render_ms.record(std::chrono::duration<double, std::milli>(end - begin).count());
    if (!first) {
      const double gap = std::chrono::duration<double, std::milli>(begin - previous).count();
      report.frame_ms.record(gap);
      const auto missed = static_cast<std::uint64_t>(gap / display_period_ms + 0.5);
      if (missed > 1) report.dropped_frames += missed - 1;
    }
    first = false;
    previous = begin;
    frames.fetch_add(1, std::memory_order_relaxed);
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    if (next < end || runtime_paces) {
      // Behind: the next frame starts at once (no catch-up burst). With OpenXR the runtime's
      // xrWaitFrame paces the frames to the headset's display; sleeping too would halve it.
      next = end;
    } else {
      std::this_thread::sleep_until(next);
    }
  }
  renderer.flush();
  if (png != nullptr) png->finish();
  report.frames = frames.load();
  report.images = png != nullptr ? png->images_written() : measuring.consumed();
}

}  // namespace bisturi::runtime
