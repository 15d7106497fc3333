// The OpenXR sink's frame loop: xrWaitFrame's pacing and what it says of the display, the views
// located at the predicted display time (invalid ones never used), the swapchain image of the
// frame, and the projection layer submitted with the very views the frame was rendered with.

#include "openxr_sink_impl.h"

#include <utility>

namespace bisturi::render {

namespace {

/// World (LPS) to the reference space: superior up (+y), anterior towards the viewer (+z), the
/// patient's left to +x; a -90 degree turn about x (see openxr_sink.h).
const glm::dquat& world_to_xr() {
  static const glm::dquat q(std::sqrt(0.5), -std::sqrt(0.5), 0.0, 0.0);  // (w, x, y, z)
  return q;
}

glm::dquat to_glm(const XrQuaternionf& q) {
  return {q.w, q.x, q.y, q.z};
}
glm::dvec3 to_glm(const XrVector3f& v) {
  return {v.x, v.y, v.z};
}

bool located(XrViewStateFlags flags) {
  return (flags & XR_VIEW_STATE_ORIENTATION_VALID_BIT) != 0 &&
         (flags & XR_VIEW_STATE_POSITION_VALID_BIT) != 0;
}

}  // namespace

glm::dvec3 OpenXrSink::to_reference_m(const glm::dvec3& world_mm) const {
  const OpenXrSinkOptions& o = impl_->options;
  return o.field_position_m + world_to_xr() * ((world_mm - o.field_centre_mm) / 1000.0);
}

glm::dvec3 OpenXrSink::Impl::world_position(const glm::dvec3& reference_m) const {
  return options.field_centre_mm +
         glm::inverse(world_to_xr()) * (reference_m - options.field_position_m) * 1000.0;
}

glm::dquat OpenXrSink::Impl::world_orientation(const glm::dquat& reference) const {
  return glm::normalize(glm::inverse(world_to_xr()) * reference);
}

std::uint32_t OpenXrSink::Impl::acquire_image() {
  std::uint32_t index = 0;
  XrSwapchainImageAcquireInfo acquire{};
  acquire.type = XR_TYPE_SWAPCHAIN_IMAGE_ACQUIRE_INFO;
  if (!xr_frame(xrAcquireSwapchainImage(swapchain, &acquire, &index), "xrAcquireSwapchainImage")) {
    return UINT32_MAX;
  }
  if (stall_next_image_wait.count() > 0) {
    // A compositor that holds on to the image: the wait blocks this long.
    std::this_thread::sleep_for(std::exchange(stall_next_image_wait, std::chrono::nanoseconds(0)));
  }
  XrSwapchainImageWaitInfo wait{};
  wait.type = XR_TYPE_SWAPCHAIN_IMAGE_WAIT_INFO;
  wait.timeout = 1'000'000'000;  // 1 s: far longer than any frame
  XrResult r = XR_TIMEOUT_EXPIRED;
  for (int tries = 0; tries < 5 && r == XR_TIMEOUT_EXPIRED; ++tries)
    r = xrWaitSwapchainImage(swapchain, &wait);
  if (r == XR_TIMEOUT_EXPIRED) throw RenderError("OpenXR xrWaitSwapchainImage timed out (5 s)");
  if (!xr_frame(r, "xrWaitSwapchainImage")) return UINT32_MAX;
  image_acquired = true;
  acquired_index = index;
  return index;
}

HeadsetFrame OpenXrSink::Impl::begin_frame() {
  HeadsetFrame frame;
  poll_events();
  try_recreate();
  if (stopped || lost || !running || session == XR_NULL_HANDLE) {
    // Nothing to show on: not ready yet, waiting for the headset, or stopped. Do not spin.
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
    return frame;
  }
  XrFrameWaitInfo wait{};
  wait.type = XR_TYPE_FRAME_WAIT_INFO;
  XrFrameState frame_state{};
  frame_state.type = XR_TYPE_FRAME_STATE;
  const auto waiting = PoseClock::now();
  const XrResult waited = xrWaitFrame(session, &wait, &frame_state);
  stats.wait_frame_ms +=
      std::chrono::duration<double, std::milli>(PoseClock::now() - waiting).count();
  if (!xr_frame(waited, "xrWaitFrame")) return frame;

  // The display's rate is the runtime's: refreshes missed are gaps between predicted display
  // times longer than one period.
  const std::int64_t period = frame_state.predictedDisplayPeriod;
  stats.display_period_ns = period;
  if (period > 0) {
    if (stats.min_display_period_ns == 0 || period < stats.min_display_period_ns) {
      stats.min_display_period_ns = period;
    }
    stats.max_display_period_ns = std::max(stats.max_display_period_ns, period);
    if (last_display_ns != 0) {
      const double gap = static_cast<double>(frame_state.predictedDisplayTime - last_display_ns);
      const auto periods =
          static_cast<std::int64_t>(std::llround(gap / static_cast<double>(period)));
      if (periods > 1) stats.dropped_frames += static_cast<std::uint64_t>(periods - 1);
    }
  }
  last_display_ns = frame_state.predictedDisplayTime;

  XrFrameBeginInfo begin{};
  begin.type = XR_TYPE_FRAME_BEGIN_INFO;
  if (!xr_frame(xrBeginFrame(session, &begin), "xrBeginFrame")) return frame;
  ++stats.frames_begun;
  frame.began = true;
  frame.display_time_ns = frame_state.predictedDisplayTime;
  frame.display_period_ns = period;
  frame.head.display_time = to_pose_clock(frame_state.predictedDisplayTime);
  if (options.controller) {
    frame.controller = read_controller(frame_state.predictedDisplayTime);
    if (session == XR_NULL_HANDLE) {  // lost while reading it
      frame.began = false;
      return frame;
    }
  }
  if (frame_state.shouldRender != XR_TRUE) {
    ++stats.frames_not_rendered;
    return frame;
  }

  // Both views at the display time, in the reference space.
  XrViewLocateInfo locate{};
  locate.type = XR_TYPE_VIEW_LOCATE_INFO;
  locate.viewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
  locate.displayTime = frame_state.predictedDisplayTime;
  locate.space = space;
  XrViewState view_state{};
  view_state.type = XR_TYPE_VIEW_STATE;
  std::array<XrView, 2> views{};
  for (XrView& v : views)
    v.type = XR_TYPE_VIEW;
  std::uint32_t count = 0;
  const auto sampled = PoseClock::now();
  if (!xr_frame(xrLocateViews(session, &locate, &view_state, 2, &count, views.data()),
                "xrLocateViews")) {
    frame.began = false;  // the session is gone with its frame
    return frame;
  }
  XrSpaceLocation head{};
  head.type = XR_TYPE_SPACE_LOCATION;
  if (!xr_frame(xrLocateSpace(view_space, space, frame_state.predictedDisplayTime, &head),
                "xrLocateSpace")) {
    frame.began = false;
    return frame;
  }
  frame.views_valid = count == 2 && located(view_state.viewStateFlags);
  if (views_log != nullptr) {
    std::fprintf(views_log, "{\"display_time\":%lld,\"flags\":%llu,\"views\":[",
                 static_cast<long long>(locate.displayTime),
                 static_cast<unsigned long long>(view_state.viewStateFlags));
    for (std::size_t e = 0; e < 2; ++e) {
      const XrView& v = views[e];
      std::fprintf(views_log,
                   "%s{\"orientation\":[%.9g,%.9g,%.9g,%.9g],\"position\":[%.9g,%.9g,%.9g],"
                   "\"fov\":[%.9g,%.9g,%.9g,%.9g]}",
                   e == 0 ? "" : ",", v.pose.orientation.x, v.pose.orientation.y,
                   v.pose.orientation.z, v.pose.orientation.w, v.pose.position.x, v.pose.position.y,
                   v.pose.position.z, v.fov.angleLeft, v.fov.angleRight, v.fov.angleUp,
                   v.fov.angleDown);
    }
    std::fprintf(views_log, "]}\n");
  }
  if (frame.views_valid) {
    last_views = views;
    have_views = true;
    const bool head_valid = (head.locationFlags & XR_SPACE_LOCATION_ORIENTATION_VALID_BIT) != 0 &&
                            (head.locationFlags & XR_SPACE_LOCATION_POSITION_VALID_BIT) != 0;
    // The head between the eyes when the runtime does not locate the VIEW space.
    last_head_m = head_valid
                      ? to_glm(head.pose.position)
                      : (to_glm(views[0].pose.position) + to_glm(views[1].pose.position)) * 0.5;
    last_head_orientation =
        head_valid ? to_glm(head.pose.orientation) : to_glm(views[0].pose.orientation);
    last_sample = sampled;
  } else {
    ++stats.invalid_view_locations;  // never drawn from: the last valid views stand in
  }
  if (!have_views) {
    ++stats.frames_without_views;
    return frame;  // should_render stays false: submitted without a layer
  }

  // The reference space's views into the world.
  for (std::size_t e = 0; e < 2; ++e) {
    const XrView& v = last_views[e];
    EyePose& eye = frame.eyes[e];
    eye.position_mm = world_position(to_glm(v.pose.position));
    eye.orientation = world_orientation(to_glm(v.pose.orientation));
    eye.fov = {v.fov.angleLeft, v.fov.angleRight, v.fov.angleUp, v.fov.angleDown};
    headset.fov[e] = eye.fov;
  }
  frame.head.position_mm = world_position(last_head_m);
  frame.head.orientation = world_orientation(last_head_orientation);
  frame.head.sample_time = last_sample;  // reused views: motion-to-photon from their sample

  if (acquire_image() == UINT32_MAX) {
    frame.began = false;
    return frame;
  }
  frame.should_render = true;
  return frame;
}

void OpenXrSink::Impl::end_frame(const HeadsetFrame& frame, bool rendered) {
  if (!frame.began || session == XR_NULL_HANDLE) return;
  if (image_acquired) {
    // The renderer submitted its commands on the shared queue: the runtime waits for them.
    XrSwapchainImageReleaseInfo release_info{};
    release_info.type = XR_TYPE_SWAPCHAIN_IMAGE_RELEASE_INFO;
    image_acquired = false;
    if (!xr_frame(xrReleaseSwapchainImage(swapchain, &release_info), "xrReleaseSwapchainImage")) {
      return;
    }
  }
  std::array<XrCompositionLayerProjectionView, 2> views{};
  XrCompositionLayerProjection layer{};
  const XrCompositionLayerBaseHeader* layers[] = {
      reinterpret_cast<const XrCompositionLayerBaseHeader*>(&layer)};
  XrFrameEndInfo end{};
  end.type = XR_TYPE_FRAME_END_INFO;
  end.displayTime = frame.display_time_ns;
  end.environmentBlendMode = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
  const bool with_layer = rendered && frame.should_render && have_views;
  if (with_layer) {
    for (std::size_t e = 0; e < 2; ++e) {
      XrCompositionLayerProjectionView& v = views[e];
      v.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW;
      v.pose = last_views[e].pose;  // exactly the views the frame was rendered with
      v.fov = last_views[e].fov;
      v.subImage.swapchain = swapchain;
      v.subImage.imageRect = {
          {0, 0}, {static_cast<std::int32_t>(width), static_cast<std::int32_t>(height)}};
      v.subImage.imageArrayIndex = static_cast<std::uint32_t>(e);
    }
    layer.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION;
    layer.space = space;
    layer.viewCount = 2;
    layer.views = views.data();
    end.layerCount = 1;
    end.layers = layers;
  }
  if (xr_frame(xrEndFrame(session, &end), "xrEndFrame") && with_layer) ++stats.frames_submitted;
}

}  // namespace bisturi::render
