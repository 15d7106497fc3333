// The session's render thread (see render_loop.h).

#include "render_loop.h"

#include "liquid_worker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <exception>
#include <limits>
#include <optional>
#include <stdexcept>
#include <thread>

#include <glm/common.hpp>
#include <glm/gtc/matrix_transform.hpp>
#include <glm/gtc/quaternion.hpp>
#include <glm/gtx/quaternion.hpp>

#include <nlohmann/json.hpp>

#include "bisturi/devices/trace/trace_format.h"
#include "bisturi/runtime/render/drape_mesh.h"
#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/instrument_mesh.h"
#include "bisturi/runtime/render/openxr_sink.h"
#include "bisturi/runtime/render/png_sink.h"
#include "bisturi/runtime/session/fault_injection.h"
#include "bisturi/scene/polygon_import.h"
#include "bisturi/sim/units.h"

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
    // Shown at the runtime's predicted display time (OpenXR), or when finished (files).
    const render::PoseClock::time_point shown =
        frame.pose.display_time.time_since_epoch().count() != 0 ? frame.pose.display_time
                                                                : frame.ready_time;
    report_.motion_to_photon_ms.record(
        std::chrono::duration<double, std::milli>(shown - frame.pose.sample_time).count());
    const Nanoseconds ready = std::chrono::duration_cast<Nanoseconds>(shown.time_since_epoch());
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

/// Where the scene sits in the headset's space (the scene's [headset] keys; see
/// scene_description.h): the field's centre defaults to the centre of the solids' bounds.
render::OpenXrSinkOptions headset_options(const SceneDescription& scene, const Snapshot& initial,
                                          const SessionReport& report) {
  render::OpenXrSinkOptions o;
  o.stage_space = scene.headset.stage_space;
  o.eye_width = report.eye_width;
  o.eye_height = report.eye_height;
  if (scene.headset.field_centre_mm) {
    const auto& c = *scene.headset.field_centre_mm;
    o.field_centre_mm = {c[0], c[1], c[2]};
  } else {
    glm::dvec3 lo(std::numeric_limits<double>::max()), hi(-std::numeric_limits<double>::max());
    for (const SolidState& s : initial.solids) {
      for (const glm::dvec3& p : s.positions_mm) {
        lo = glm::min(lo, p);
        hi = glm::max(hi, p);
      }
    }
    if (lo.x <= hi.x) o.field_centre_mm = (lo + hi) * 0.5;
  }
  const double height =
      scene.headset.field_height_m.value_or(scene.headset.stage_space ? 0.95 : -0.35);
  o.field_position_m = {0.0, height, -scene.headset.field_distance_m};
  return o;
}

/// The runtime's head pose of a drawn frame, for the trace.
std::string head_note(const render::HeadsetFrame& f) {
  const nlohmann::json j = {
      {"xr_head",
       {{"display_time_ns", f.display_time_ns},
        {"views_valid", f.views_valid},
        {"position_mm", {f.head.position_mm.x, f.head.position_mm.y, f.head.position_mm.z}},
        {"orientation_wxyz",
         {f.head.orientation.w, f.head.orientation.x, f.head.orientation.y,
          f.head.orientation.z}}}}};
  return j.dump();
}

/// The headset's figures into the report; the display rate and dropped frames are the runtime's.
void report_headset(const render::OpenXrSink& xr, const render::StereoRenderer& renderer,
                    render::PoseClock::time_point origin, SessionReport& report) {
  HeadsetReport& h = report.headset;
  const render::OpenXrSinkStats st = xr.stats();
  h.sink = "openxr";
  h.runtime = xr.runtime_name();
  h.reference_space = xr.reference_space();
  h.swapchain_format = xr.swapchain_format();
  h.eye_width = renderer.options().headset.eye_width;
  h.eye_height = renderer.options().headset.eye_height;
  h.display_period_ms = static_cast<double>(st.display_period_ns) * 1e-6;
  h.min_display_period_ms = static_cast<double>(st.min_display_period_ns) * 1e-6;
  h.max_display_period_ms = static_cast<double>(st.max_display_period_ns) * 1e-6;
  h.display_hz = st.display_period_ns > 0 ? 1e9 / static_cast<double>(st.display_period_ns) : 0.0;
  h.frames_begun = st.frames_begun;
  h.frames_submitted = st.frames_submitted;
  h.frames_not_rendered = st.frames_not_rendered;
  h.frames_without_views = st.frames_without_views;
  h.dropped_frames = st.dropped_frames;
  h.invalid_view_locations = st.invalid_view_locations;
  h.states.clear();
  for (const render::XrStateChange& c : xr.state_changes())
    h.states.push_back({c.state, std::chrono::duration<double>(c.time - origin).count()});
  h.sessions_lost = st.sessions_lost;
  h.sessions_recreated = st.sessions_recreated;
  h.shared_device = renderer.draws_into_headset();
  h.frames_read_back = renderer.frames_read_back();
  h.frames_crossed_cpu = h.frames_read_back > 0;
  for (std::size_t e = 0; e < 2; ++e) {
    const render::EyeFov& f = xr.headset().fov[e];
    h.fov[e] = {f.angle_left, f.angle_right, f.angle_up, f.angle_down};
  }
  h.stop_reason = xr.stop_reason();
  h.note =
      "views, head pose and pacing from the OpenXR runtime; the scene's head tracker does not "
      "place the views";
  if (h.display_hz > 0.0) report.display_hz = h.display_hz;
  report.dropped_frames = h.dropped_frames;
}

/// The frame's controller into the haptic device's feed, and the newest vibration its driver wrote
/// back onto the controller (each held for two display periods, so that a steady contact hums
/// without gaps; a zero after a nonzero one stops it).
void feed_controller(devices::ControllerFeed& feed, const render::HeadsetFrame& frame,
                     render::OpenXrSink& xr, double& last_amplitude, bool located) {
  const render::ControllerState& cs = frame.controller;
  devices::ControllerSample sample;
  sample.t_ns =
      std::chrono::duration_cast<std::chrono::nanoseconds>(cs.sample_time.time_since_epoch())
          .count();
  sample.active = cs.active && located;
  const glm::dvec3 p_m = sim::scene_to_sim(cs.grip_mm);
  sample.position_m = {p_m.x, p_m.y, p_m.z};
  const glm::dquat q = glm::normalize(cs.grip_orientation);
  sample.orientation = {q.w, q.x, q.y, q.z};
  sample.trigger = static_cast<double>(cs.trigger);
  feed.push(sample);
  const std::optional<double> amplitude = feed.take_vibration();
  if (!amplitude || (*amplitude == 0.0 && last_amplitude == 0.0)) return;
  const double hold_s = 2.0 * static_cast<double>(frame.display_period_ns) * 1e-9;
  xr.vibrate(static_cast<float>(*amplitude), *amplitude > 0.0 ? hold_s : 0.0);
  last_amplitude = *amplitude;
}

/// A finer drawn surface to its volume's nodes now, cut by the incisions made on its solid since
/// the last frame; its figures into `report`.
void follow_drawn(DrawnSurface& drawn, const SolidState& state,
                  const std::vector<Incision>& incisions, std::size_t seen, std::size_t body,
                  SolidReport& report) {
  drawn.use_lattice(state.lattice);
  drawn.follow(state.nodes_m);
  for (std::size_t k = seen; k < incisions.size(); ++k) {
    if (incisions[k].body != body) continue;
    if (drawn.cut(incisions[k].points_m, incisions[k].tips_m)) {
      ++report.drawn_cuts;
    } else {
      ++report.drawn_cuts_missed;
    }
  }
  report.drawn_most_gap_mm = std::max(report.drawn_most_gap_mm, drawn.gap_mm(state.positions_mm));
}

/// A frame's draws and culled triangles into a window's sums.
void add_culling(SessionReport::Culling& w, const render::FrameStats& stats, double render_ms) {
  ++w.frames;
  w.draw_calls += static_cast<double>(stats.draw_calls);
  w.triangles_submitted += static_cast<double>(stats.triangles_drawn);
  w.culled_frustum += static_cast<double>(stats.triangles_culled_frustum);
  w.culled_occlusion += static_cast<double>(stats.triangles_culled_occlusion);
  w.culled_portal += static_cast<double>(stats.triangles_culled_portal);
  w.render_ms.record(render_ms);
}

/// The sums to per-frame means.
void average_culling(SessionReport::Culling& w) {
  if (w.frames == 0) return;
  const auto n = static_cast<double>(w.frames);
  for (double* x : {&w.draw_calls, &w.triangles_submitted, &w.culled_frustum, &w.culled_occlusion,
                    &w.culled_portal})
    *x /= n;
}

/// The background (linear RGB): a dark shade of surgical drape green, not a black void.
constexpr glm::vec3 kFieldBackground{0.035f, 0.098f, 0.091f};
/// The drape under the solids: the same green, lit (linear RGB, cloth: no highlight).
constexpr glm::vec3 kDrapeColour{0.040f, 0.115f, 0.100f};
/// Blood steps queued on the blood's thread from which its surface is built from every other
/// step (half the hold's default: falling behind, not yet held).
constexpr std::uint64_t kBloodBehindToBuildEveryOther = 2;

}  // namespace

namespace {

/// Sets `stop` when the scope it lives in is left by an exception.
class StopOnUnwind {
 public:
  explicit StopOnUnwind(std::atomic<bool>& stop)
      : stop_(stop), exceptions_(std::uncaught_exceptions()) {}
  StopOnUnwind(const StopOnUnwind&) = delete;
  StopOnUnwind& operator=(const StopOnUnwind&) = delete;
  ~StopOnUnwind() {
    if (std::uncaught_exceptions() > exceptions_) stop_.store(true);
  }

 private:
  std::atomic<bool>& stop_;
  int exceptions_;
};

}  // namespace

void run_render_loop(const RenderLoopContext& c) {
  const SceneDescription& scene = c.scene;
  const SessionOptions& options = c.options;
  SessionReport& report = c.report;
  const Snapshot& initial = c.initial;
  TripleBuffer<Snapshot>& handoff = c.snapshots;
  TripleBuffer<render::HeadPose>& head_handoff = c.head_poses;
  std::atomic<bool>& stop = c.stop;
  devices::Clock& clock = options.clock != nullptr ? *options.clock : devices::steady_clock();
  std::atomic<bool>& render_ready = c.ready;
  std::atomic<std::uint64_t>& frames = c.frames;
  std::vector<double>& event_response = c.event_response_ms;
  std::vector<Nanoseconds>& event_times = c.event_times;
  const double display_period_ms = 1000.0 / report.display_hz;
  render::RendererOptions ro;
  ro.device = options.render_device;
  if (options.occlusion_culling) ro.occlusion_cells = render::kOcclusionCells;
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
  // An operating field, not a void: a dark drape-green background and an operating lamp whose
  // light falls off past the organs (a depth cue).
  ro.clear_colour = kFieldBackground;
  ro.field_lamp = true;
  // The headset first: the renderer draws on its device (and goes before it).
  std::unique_ptr<render::OpenXrSink> xr;
  if (options.openxr) {
    try {
      render::OpenXrSinkOptions xo = headset_options(scene, initial, report);
      xo.controller = c.controller != nullptr;
      xr = std::make_unique<render::OpenXrSink>(xo);
      report.sink = "openxr";
    } catch (const render::XrUnavailable& e) {
      report.sink_note =
          std::string("OpenXR unavailable (") + e.what() + "): frames go to the PNG sink";
    }
  }
  if (c.controller != nullptr && !xr)
    throw std::runtime_error(
        "the scene's haptic device uses driver '" + std::string(devices::kOpenXrControllerDriver) +
        "', which needs an OpenXR headset, and there is none (" +
        (options.openxr ? report.sink_note : std::string("OpenXR is turned off")) + ")");
  std::unique_ptr<render::StereoRenderer> renderer_owner =
      xr ? std::make_unique<render::StereoRenderer>(ro, *xr)
         : std::make_unique<render::StereoRenderer>(ro);
  render::StereoRenderer& renderer = *renderer_owner;
  report.render_device = renderer.device_name();
  report.render_device_is_cpu = renderer.device_is_cpu();
  if (xr) {
    report.eye_width = renderer.options().headset.eye_width;
    report.eye_height = renderer.options().headset.eye_height;
  }
  std::unique_ptr<render::FrameSink> png_owner;
  render::PngSink* png = nullptr;
  if (!xr && !options.frames_dir.empty()) {
    auto p = std::make_unique<render::PngSink>(
        options.frames_dir,
        render::PngSinkOptions{render::PngLayout::SideBySide, options.image_every});
    png = p.get();
    png_owner = std::move(p);
    report.sink = "png";
  }
  if (!xr && !png) report.sink = "none";
  render::FrameSink* sink = xr ? static_cast<render::FrameSink*>(xr.get()) : png_owner.get();
  c.display_live.store(!xr);
  if (xr && c.headset_sink != nullptr) c.headset_sink->store(true);
  MeasuringSink measuring(sink, report, event_response, event_times);
  renderer.set_sink(&measuring);

  std::vector<RenderSolid> meshes(initial.solids.size());
  std::vector<render::SolidId> ids;
  // A solid with a finer drawn surface is drawn by it (drawn_surface.h).
  std::vector<DrawnSurface*> drawn(initial.solids.size(), nullptr);
  for (std::size_t b = 0; c.drawn != nullptr && b < std::min(drawn.size(), c.drawn->size()); ++b)
    drawn[b] = (*c.drawn)[b].get();
  std::size_t incisions_seen = 0;
  for (std::size_t b = 0; b < initial.solids.size(); ++b) {
    meshes[b].rebuild(*initial.solids[b].topology);
    meshes[b].set_positions(initial.solids[b].positions_mm);
    const auto& rgb = scene.solids[b].material.colour;
    render::Material m;
    m.colour = glm::vec3(static_cast<float>(rgb[0]), static_cast<float>(rgb[1]),
                         static_cast<float>(rgb[2]));
    // Its soft shadow is in the drape's shading: no hard one on a GPU besides.
    m.casts_shadow = c.shading == nullptr;
    ids.push_back(renderer.add_solid(drawn[b] != nullptr ? drawn[b]->mesh() : meshes[b].mesh, m));
  }
  // Structures inside the solids: drawn only where they can be seen past them.
  std::vector<render::SolidId> inner_ids;
  for (std::size_t k = 0; c.inner != nullptr && k < c.inner->size(); ++k) {
    const InnerStructure& in = (*c.inner)[k];
    render::Material m;
    m.colour = glm::vec3(static_cast<float>(in.colour[0]), static_cast<float>(in.colour[1]),
                         static_cast<float>(in.colour[2]));
    m.interior_colour = m.colour;
    inner_ids.push_back(renderer.add_solid(in.surface->mesh(), m));
    renderer.set_enclosed_by(inner_ids.back(), ids[in.solid]);
  }
  // The drape the solids lie on, at the blood's tray: lit by the lamp, the floor of the field,
  // darkened where the solids hide its sky (field_occlusion.h).
  if (c.shading != nullptr && c.shading->drape.num_faces() > 0) {
    render::Material drape;
    drape.colour = kDrapeColour;
    drape.interior_colour = kDrapeColour;
    drape.specular = 0.0f;
    drape.casts_shadow = false;
    const render::SolidId drape_id = renderer.add_solid(c.shading->drape, drape);
    renderer.set_occlusion(drape_id, c.shading->drape_open);
    // The instruments' shadows on it, on a GPU (the solids' soft shadows are in its shading): on
    // a CPU rasterizer (lavapipe) they cost about 3.5 ms a frame at 256 x 256 an eye, which
    // takes the display below 90 Hz.
    if (!renderer.device_is_cpu()) renderer.set_shadow_plane(c.shading->drape_z_mm);
  }
  // Each solid's occlusion, by the vertices it is drawn with.
  const auto shade = [&](std::size_t b) {
    if (c.shading == nullptr || b >= c.shading->solid_open.size()) return;
    const std::vector<float>& open = c.shading->solid_open[b];
    if (drawn[b] != nullptr) {
      renderer.set_occlusion(ids[b], open);
      return;
    }
    std::vector<float> by_vertex(meshes[b].mesh.vertex_capacity(), 1.0f);
    for (const auto& [slot, v] : meshes[b].slot_to_vertex)
      if (slot < open.size() && v.idx < by_vertex.size()) by_vertex[v.idx] = open[slot];
    renderer.set_occlusion(ids[b], std::move(by_vertex));
  };
  for (std::size_t b = 0; b < ids.size(); ++b)
    shade(b);
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
  render::Material blade_material = steel;
  blade_material.colour = {0.95f, 0.95f, 1.0f};
  // Each hand's probe and blade (the blade shows while it cuts).
  std::vector<render::SolidId> probe_ids, blade_ids;
  for (std::size_t h = 0; h < initial.instruments.size(); ++h) {
    probe_ids.push_back(renderer.add_instrument(render::capsule_solid(probe_radius, probe_length),
                                                steel, glm::dmat4(1.0)));
    blade_ids.push_back(
        renderer.add_instrument(render::capsule_solid(0.4, 1.0), blade_material, glm::dmat4(1.0)));
    renderer.set_visible(blade_ids.back(), false);
  }
  // Blood, where a cut may open a pulsing vessel: a liquid surface round its particles, built
  // on a thread of its own from the newest particles while there are any.
  std::optional<LiquidWorker> blood;
  render::SolidId blood_id{};
  bool blood_drawn = false;
  std::uint64_t blood_surface_drawn = 0;  // the number of the surface drawn (LiquidWorker)
  const bool may_bleed = std::any_of(scene.solids.begin(), scene.solids.end(),
                                     [](const SolidDescription& d) { return d.pulse_mmHg; });
  if (may_bleed && scene.physiology.blood_max_particles > 0) {
    blood.emplace();
    render::Material wet_blood;
    wet_blood.colour = {0.36f, 0.01f, 0.02f};
    wet_blood.specular = 0.6f;
    wet_blood.shininess = 64.0f;
    wet_blood.interior_colour = wet_blood.colour;
    wet_blood.casts_shadow = false;
    blood_id = renderer.add_solid(Dlfl{}, wet_blood);
    renderer.set_visible(blood_id, false);
  }
  render_ready.store(true);
  const render::PoseClock::time_point origin = render::PoseClock::now();  // ~ the haptic start

  std::uint64_t seen_events = 0;
  const auto period = std::chrono::duration<double, std::milli>(display_period_ms);
  auto next = std::chrono::steady_clock::now();
  auto previous = next;
  bool first = true;
  double last_amplitude = 0.0;                              // the controller's vibration now
  std::chrono::steady_clock::time_point unlocated_until{};  // an injected tracking loss
  // The first frame waits for the first snapshot (the haptic thread's start).
  while (!stop.load(std::memory_order_relaxed) && !handoff.take())
    std::this_thread::sleep_for(std::chrono::microseconds(200));
  const std::chrono::nanoseconds display_timeout =
      xr ? std::chrono::nanoseconds(kHeadsetDisplayTimeout) : kFileDisplayTimeout;
  report.headset.display_timeout_ms =
      std::chrono::duration<double, std::milli>(display_timeout).count();
  const auto came_round = [&] {
    if (c.display_deadline_ns != nullptr)
      c.display_deadline_ns->store((clock.now() + display_timeout).count(),
                                   std::memory_order_release);
  };
  // A frame that throws stops the session before the renderer and the rest of this loop's
  // state are torn down (waiting for the device and freeing it took lavapipe over 100 ms under
  // load): the haptic thread zeroes the force first.
  const StopOnUnwind stop_on_fault(stop);
  while (!stop.load(std::memory_order_relaxed)) {
    came_round();
    if (c.fail_next_frame != nullptr && c.fail_next_frame->exchange(false))
      throw std::runtime_error("injected fault: render-throw");
    if (c.hang_next_frame != nullptr && c.hang_next_frame->exchange(false))
      std::this_thread::sleep_for(std::chrono::duration<double>(kFaultHangSeconds));
    render::HeadsetFrame xr_frame;
    if (xr) {
      // The runtime's frame: paced by xrWaitFrame, posed by its views.
      xr_frame = xr->begin_frame();
      c.display_live.store(xr->presenting());
      if (xr->stopped()) {
        stop.store(true);  // the user exited or the runtime went away: the session ends
        break;
      }
      if (!xr_frame.began) continue;
      if (c.stall_swapchain != nullptr && c.stall_swapchain->exchange(false))
        xr->stall_next_image_wait(std::chrono::duration_cast<std::chrono::nanoseconds>(
            std::chrono::duration<double>(kFaultHangSeconds)));
      if (c.controller != nullptr) {
        if (c.lose_controller != nullptr && c.lose_controller->exchange(false))
          unlocated_until = std::chrono::steady_clock::now() +
                            std::chrono::duration_cast<std::chrono::steady_clock::duration>(
                                std::chrono::duration<double>(kFaultHangSeconds));
        feed_controller(*c.controller, xr_frame, *xr, last_amplitude,
                        std::chrono::steady_clock::now() >= unlocated_until);
      }
    }
    const auto begin = std::chrono::steady_clock::now();
    handoff.take();
    const Snapshot& s = handoff.front();
    for (std::size_t b = 0; b < s.solids.size(); ++b) {
      const SolidState& st = s.solids[b];
      if (drawn[b] != nullptr) {
        const std::uint64_t cuts = drawn[b]->cuts();
        follow_drawn(*drawn[b], st, s.incisions, incisions_seen, b, report.solids[b]);
        if (drawn[b]->cuts() != cuts) {
          renderer.recut_solid(ids[b], drawn[b]->mesh());
        } else {
          renderer.update_solid(ids[b], drawn[b]->mesh());
        }
      } else {
        const bool cut = st.topology->version != meshes[b].version;
        if (cut) meshes[b].rebuild(*st.topology);
        meshes[b].set_positions(st.positions_mm);
        if (cut) {
          // Rebuilt here: its topology version counts this copy's edits, not the simulated one's.
          renderer.replace_solid(ids[b], meshes[b].mesh);
          shade(b);  // renumbered
        } else {
          renderer.update_solid(ids[b], meshes[b].mesh);
        }
      }
    }
    if (incisions_seen == 0 && !s.incisions.empty())
      report.first_cut_tick = static_cast<std::int64_t>(s.tick);
    incisions_seen = s.incisions.size();
    for (std::size_t k = 0; k < inner_ids.size(); ++k) {
      DrawnSurface& in = *(*c.inner)[k].surface;
      const SolidState& st = s.solids[(*c.inner)[k].solid];
      in.use_lattice(st.lattice);
      in.follow(st.nodes_m);
      renderer.update_solid(inner_ids[k], in.mesh());
    }
    // The blood's surface: the newest particles to its thread, the newest surface it built drawn;
    // while the blood's thread is behind, from every other step it makes (liquid_worker.h).
    if (blood && (!s.blood_mm.empty() || blood_drawn)) {
      blood->offer(s.blood_mm, s.blood_behind >= kBloodBehindToBuildEveryOther);
      std::uint64_t number = 0;
      const std::shared_ptr<const Dlfl> surface = blood->newest(number);
      if (surface && number != blood_surface_drawn) {
        renderer.replace_solid(blood_id, *surface);
        blood_surface_drawn = number;
        blood_drawn = surface->num_faces() > 0;
        renderer.set_visible(blood_id, blood_drawn);
      }
    }
    // Each probe's shaft rises from its tip along the hand; a blade shows while it cuts.
    for (std::size_t h = 0; h < std::min(s.instruments.size(), probe_ids.size()); ++h) {
      const InstrumentState& in = s.instruments[h];
      const glm::dvec3 along = in.blade_to_mm - in.tip_mm;
      const double along_len = glm::length(along);
      const glm::dvec3 dir = along_len > 1e-9 ? along / along_len : glm::dvec3(0, 0, 1);
      renderer.set_pose(probe_ids[h], instrument_pose(in.tip_mm, in.tip_mm + dir * probe_length));
      renderer.set_visible(blade_ids[h], in.cutting);
      if (in.cutting) {
        glm::dmat4 m = instrument_pose(in.tip_mm, in.blade_to_mm);
        m = m * glm::scale(glm::dmat4(1.0),
                           glm::dvec3(1.0, 1.0, glm::length(in.blade_to_mm - in.tip_mm)));
        renderer.set_pose(blade_ids[h], m);
      }
    }
    render::FrameStats stats;
    if (xr) {
      if (xr_frame.should_render) stats = renderer.render(xr_frame.head, xr_frame.eyes);
      if (xr_frame.should_render && c.writer != nullptr) {
        try {
          c.writer->note(clock.now().count(), head_note(xr_frame));
        } catch (const devices::TraceError&) {
          // The recording failed; the haptic loop reports why. Frames go on.
        }
      }
      xr->end_frame(xr_frame, xr_frame.should_render);
      if (!xr_frame.should_render) continue;  // nothing drawn: no frame to time
    } else {
      head_handoff.take();
      stats = renderer.render(head_handoff.front());
    }
    for (; seen_events < s.event_count; ++seen_events) {
      if (s.event_count - seen_events <= s.recent.size()) measuring.shows(stats.frame, seen_events);
    }
    const auto end = std::chrono::steady_clock::now();
    const double render_ms = std::chrono::duration<double, std::milli>(end - begin).count();
    report.render_ms.record(render_ms);
    add_culling(incisions_seen == 0 ? report.before_cut : report.after_cut, stats, render_ms);
    if (!first) {
      const double gap = std::chrono::duration<double, std::milli>(begin - previous).count();
      report.frame_ms.record(gap);
      // With OpenXR the runtime's display periods count the dropped frames (report_headset).
      const auto missed = static_cast<std::uint64_t>(gap / display_period_ms + 0.5);
      if (missed > 1 && !xr) report.dropped_frames += missed - 1;
    }
    first = false;
    previous = begin;
    frames.fetch_add(1, std::memory_order_relaxed);
    next += std::chrono::duration_cast<std::chrono::steady_clock::duration>(period);
    if (next < end || xr) {
      // Behind: the next frame starts at once (no catch-up burst). With OpenXR the runtime's
      // xrWaitFrame paces the frames to the headset's display; sleeping too would halve it.
      next = end;
    } else {
      std::this_thread::sleep_until(next);
    }
  }
  renderer.flush();
  for (SessionReport::Culling* w : {&report.before_cut, &report.after_cut})
    average_culling(*w);
  c.display_live.store(false);
  if (xr) {
    const std::string reason = xr->stop_reason();  // before finish() gives its own
    xr->finish();
    report_headset(*xr, renderer, origin, report);
    report.headset.stop_reason = reason;
  }
  if (png != nullptr) png->finish();
  report.frames = frames.load();
  report.images = png != nullptr ? png->images_written() : measuring.consumed();
}

}  // namespace bisturi::runtime
