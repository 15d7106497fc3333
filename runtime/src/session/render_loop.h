#pragma once
// The session's render thread: at the headset's rate it takes the newest snapshot of the solids
// and instruments and the newest head pose, draws both eyes (StereoRenderer) and hands the frame to
// the sink (OpenXR when a runtime is there, PNG files otherwise), measuring frame times,
// motion-to-photon and action-to-response into the report.

#include <atomic>
#include <cstdint>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/runtime/render/headset.h"
#include "bisturi/runtime/session/scene_description.h"
#include "bisturi/runtime/session/session.h"
#include "bisturi/runtime/session/triple_buffer.h"
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
  const std::atomic<bool>& stop;  ///< the loop ends when set
  std::atomic<bool>& ready;       ///< set once the renderer is up (or failed)
  std::atomic<std::uint64_t>& frames;
  /// Per event: ms from its device report to the first frame showing it (written here).
  std::vector<double>& event_response_ms;
  /// Per event: when its device report was read (written by the tissue thread).
  std::vector<devices::Nanoseconds>& event_times;
};

/// Runs until `stop`. Throws render::RenderError (no Vulkan device) and what the sinks throw.
void run_render_loop(const RenderLoopContext& context);

}  // namespace bisturi::runtime
