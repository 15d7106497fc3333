#pragma once
// The session's render thread: at the headset's rate it takes the newest snapshot of the solids
// and instruments, draws both eyes (StereoRenderer) and hands the frame to the sink, measuring
// frame times, motion-to-photon and action-to-response into the report.
//  - OpenXR (when a runtime is there): the runtime paces the loop (xrWaitFrame), locates the views
//    and the head at the predicted display time, and the frame is drawn with those views straight
//    into its swapchain on the device it shares; motion-to-photon runs from the views' sample to
//    the predicted display time. The scene's head tracker does not place the views then.
//  - PNG files otherwise: the loop paces itself to the scene's display rate and draws the head
//    pose the haptic thread publishes (the scene's head tracker).

#include <atomic>
#include <cstdint>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/controller/openxr_controller.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/triple_buffer.h"
#include "drawn_surface.h"
#include "field_occlusion.h"
#include "session_snapshot.h"

namespace bisturi::runtime {

/// What the render thread shares with the rest of the session (all owned by run_session).
struct RenderLoopContext {
  const SceneDescription& scene;
  const SessionOptions& options;
  SessionReport& report;  ///< render_* fields, frames, images, sink, render device
  const Snapshot& initial;
  TripleBuffer<Snapshot>& snapshots;
  TripleBuffer<render::HeadPose>& head_poses;
  /// The loop ends when set; set here when the headset is gone for good (the user exited, the
  /// runtime went away): the session ends with it.
  std::atomic<bool>& stop;
  std::atomic<bool>& ready;  ///< set once the renderer is up (or failed)
  std::atomic<std::uint64_t>& frames;
  /// Per event: ms from its device report to the first frame showing it (written here).
  std::vector<double>& event_response_ms;
  /// Per event: when its device report was read (written by the tissue thread).
  std::vector<devices::Nanoseconds>& event_times;
  /// False while an OpenXR headset shows nothing (not yet visible, session lost): the haptic
  /// loop holds its forces at zero then. Always true with the PNG sink.
  std::atomic<bool>& display_live;
  /// The session's recording (null: none): with OpenXR each drawn frame's head pose, as the
  /// runtime located it, goes in as an "xr_head" note.
  devices::TraceWriter* writer = nullptr;
  /// The haptic device is the headset's controller (driver openxr-controller; null: it is not):
  /// each frame's grip pose and trigger go into it, and the vibration its driver writes back is
  /// applied to the controller. It needs the OpenXR sink: without one the loop throws.
  devices::ControllerFeed* controller = nullptr;
  /// Set (an injected render-throw): the next frame throws, as a failing renderer would.
  std::atomic<bool>* fail_next_frame = nullptr;
  /// Set (an injected render-hang): the next frame stops for kFaultHangSeconds first.
  std::atomic<bool>* hang_next_frame = nullptr;
  /// Set (an injected controller-tracking-lost): the controller is fed as not located for
  /// kFaultHangSeconds.
  std::atomic<bool>* lose_controller = nullptr;
  /// Set (an injected headset-swapchain-stall): the next swapchain image wait blocks
  /// kFaultHangSeconds. `headset_sink` is set once frames go to OpenXR.
  std::atomic<bool>* stall_swapchain = nullptr;
  std::atomic<bool>* headset_sink = nullptr;
  /// Clock time (the devices' clock) by which the loop must come round again: each time round it
  /// moves on by the display timeout (kHeadsetDisplayTimeout on a headset, kFileDisplayTimeout
  /// when frames go to files). The haptic loop holds its forces at zero once it has passed.
  std::atomic<std::int64_t>* display_deadline_ns = nullptr;
  /// Per solid, the finer surface drawn in its place (null: its simulated surface is drawn).
  /// The loop moves them with their volumes, cuts them with the simulation's incisions and
  /// writes their figures into the report's solids.
  std::vector<std::unique_ptr<DrawnSurface>>* drawn = nullptr;
  /// Structures inside the solids: moved with their volumes, each drawn only while it can be
  /// seen past its solid (StereoRenderer::set_enclosed_by).
  std::vector<InnerStructure>* inner = nullptr;
  /// The drape and the field's ambient occlusion (null: no drape, no occlusion).
  const FieldShading* shading = nullptr;
};

/// A headset's picture frozen this long stops the forces (18 frames at 90 Hz).
constexpr std::chrono::milliseconds kHeadsetDisplayTimeout{200};
/// Frames that go to files: no one watches them live, only a renderer stuck for good counts
/// (a CPU renderer on a loaded machine takes up to 150 ms for a frame).
constexpr std::chrono::milliseconds kFileDisplayTimeout{1000};

/// Runs until `stop`. Throws render::RenderError (no Vulkan device) and what the sinks throw.
void run_render_loop(const RenderLoopContext& context);

}  // namespace bisturi::runtime
