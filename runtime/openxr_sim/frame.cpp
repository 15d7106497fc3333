// The frame loop: xrWaitFrame paced to the display rate, xrBeginFrame, and xrEndFrame, where the
// "compositor" reads back each projection view's image and the log records what arrived.

#include <array>
#include <chrono>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <thread>

#include "api.h"

namespace bisturi::xrsim {

namespace {

struct EyeStats {
  std::array<double, 3> mean{};
  std::array<std::uint8_t, 4> centre{};
  std::uint64_t checksum = 0;
};

/// Mean colour, centre texel and FNV-1a of the rectangle's texels, all in RGBA byte order (a BGRA
/// image is swizzled first) so the test can compute the same over the frame it sent.
EyeStats measure(const Swapchain& chain, const XrRect2Di& rect, std::vector<std::uint8_t>& rgba) {
  EyeStats stats;
  const auto w = static_cast<std::uint32_t>(rect.extent.width);
  const auto h = static_cast<std::uint32_t>(rect.extent.height);
  rgba.resize(std::size_t{w} * h * 4);
  const auto* texels = static_cast<const std::uint8_t*>(chain.mapped);
  const bool bgra = chain.format == VK_FORMAT_B8G8R8A8_SRGB;
  std::uint64_t hash = 1469598103934665603ull;
  std::array<std::uint64_t, 3> sum{};
  for (std::uint32_t y = 0; y < h; ++y) {
    const std::uint8_t* row =
        texels + (std::size_t{y + static_cast<std::uint32_t>(rect.offset.y)} * chain.width +
                  static_cast<std::uint32_t>(rect.offset.x)) *
                     4;
    std::uint8_t* out = rgba.data() + std::size_t{y} * w * 4;
    for (std::uint32_t x = 0; x < w; ++x) {
      const std::uint8_t* t = row + std::size_t{x} * 4;
      const std::uint8_t px[4] = {bgra ? t[2] : t[0], t[1], bgra ? t[0] : t[2], t[3]};
      for (int c = 0; c < 4; ++c) {
        out[x * 4 + static_cast<std::uint32_t>(c)] = px[c];
        hash = (hash ^ px[c]) * 1099511628211ull;
      }
      for (std::size_t c = 0; c < 3; ++c)
        sum[c] += px[c];
    }
  }
  const double n = static_cast<double>(std::size_t{w} * h);
  for (std::size_t c = 0; c < 3; ++c)
    stats.mean[c] = n > 0 ? static_cast<double>(sum[c]) / n : 0.0;
  if (w > 0 && h > 0) {
    const std::size_t i = (std::size_t{h / 2} * w + w / 2) * 4;
    for (std::size_t c = 0; c < 4; ++c)
      stats.centre[c] = rgba[i + c];
  }
  stats.checksum = hash;
  return stats;
}

std::string view_json(int eye, const XrCompositionLayerProjectionView& v, const EyeStats* stats) {
  const float position[3] = {v.pose.position.x, v.pose.position.y, v.pose.position.z};
  const float orientation[4] = {v.pose.orientation.x, v.pose.orientation.y, v.pose.orientation.z,
                                v.pose.orientation.w};
  const float fov[4] = {v.fov.angleLeft, v.fov.angleRight, v.fov.angleUp, v.fov.angleDown};
  const XrRect2Di& r = v.subImage.imageRect;
  std::string out =
      "{\"eye\":" + std::to_string(eye) + ",\"position\":" + json_floats(position, 3) +
      ",\"orientation\":" + json_floats(orientation, 4) + ",\"fov\":" + json_floats(fov, 4) +
      ",\"rect\":[" + std::to_string(r.offset.x) + "," + std::to_string(r.offset.y) + "," +
      std::to_string(r.extent.width) + "," + std::to_string(r.extent.height) + "]";
  if (stats != nullptr) {
    char text[160];
    std::snprintf(text, sizeof text,
                  ",\"mean_rgb\":[%.3f,%.3f,%.3f],\"centre_rgba\":[%u,%u,%u,%u],"
                  "\"checksum\":\"%016" PRIx64 "\"",
                  stats->mean[0], stats->mean[1], stats->mean[2], stats->centre[0],
                  stats->centre[1], stats->centre[2], stats->centre[3], stats->checksum);
    out += text;
  }
  return out + "}";
}

bool finite(float v) {
  return std::isfinite(v);
}

/// A pose a compositor can use: finite, with a unit quaternion.
bool valid_pose(const XrPosef& p) {
  const XrQuaternionf& q = p.orientation;
  const float norm = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
  return finite(p.position.x) && finite(p.position.y) && finite(p.position.z) && finite(norm) &&
         std::abs(norm - 1.0f) < 1e-3f;
}

/// A field of view a compositor can project: finite, left of right, below up, under 90 degrees.
bool valid_fov(const XrFovf& f) {
  const float limit = 1.5707f;
  return finite(f.angleLeft) && finite(f.angleRight) && finite(f.angleUp) && finite(f.angleDown) &&
         f.angleLeft < f.angleRight && f.angleDown < f.angleUp && std::abs(f.angleLeft) < limit &&
         std::abs(f.angleRight) < limit && std::abs(f.angleUp) < limit &&
         std::abs(f.angleDown) < limit;
}

/// Checks one projection layer; XR_SUCCESS when the compositor could show it.
XrResult check_layer(const Session& s, const XrCompositionLayerProjection& layer) {
  const Space* space = object<Space>(layer.space);
  if (space == nullptr || space->session != &s) return XR_ERROR_HANDLE_INVALID;
  if (layer.viewCount != 2 || layer.views == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  for (std::uint32_t i = 0; i < 2; ++i) {
    const XrCompositionLayerProjectionView& v = layer.views[i];
    if (v.type != XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW) return XR_ERROR_VALIDATION_FAILURE;
    if (!valid_pose(v.pose)) return XR_ERROR_POSE_INVALID;
    if (!valid_fov(v.fov)) return XR_ERROR_VALIDATION_FAILURE;
    const Swapchain* chain = object<Swapchain>(v.subImage.swapchain);
    if (chain == nullptr || chain->session != &s) return XR_ERROR_HANDLE_INVALID;
    if (chain->released < 0) return XR_ERROR_LAYER_INVALID;  // nothing released yet
    const XrRect2Di& r = v.subImage.imageRect;
    if (r.offset.x < 0 || r.offset.y < 0 || r.extent.width <= 0 || r.extent.height <= 0 ||
        static_cast<std::uint32_t>(r.offset.x + r.extent.width) > chain->width ||
        static_cast<std::uint32_t>(r.offset.y + r.extent.height) > chain->height) {
      return XR_ERROR_SWAPCHAIN_RECT_INVALID;
    }
    if (v.subImage.imageArrayIndex >= chain->array_size) return XR_ERROR_VALIDATION_FAILURE;
  }
  return XR_SUCCESS;
}

}  // namespace

XrResult WaitFrame(XrSession handle_, const XrFrameWaitInfo* /*info*/, XrFrameState* state) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (state == nullptr || state->type != XR_TYPE_FRAME_STATE) return XR_ERROR_VALIDATION_FAILURE;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  // Pacing: at most one frame per display period. A late application gets the next display
  // time still ahead (the refreshes it missed are gone), as a compositor predicts.
  std::int64_t now = now_ns();
  if (s->next_display_ns == 0) s->next_display_ns = now + s->period_ns;
  while (s->next_display_ns <= now)
    s->next_display_ns += s->period_ns;
  const std::int64_t slot_start = s->next_display_ns - s->period_ns;
  if (slot_start > now) std::this_thread::sleep_for(std::chrono::nanoseconds(slot_start - now));
  s->predicted_display_ns = s->next_display_ns;
  s->next_display_ns += s->period_ns;
  // The frame loop is synchronized once the application waits its first frame.
  if (s->state == XR_SESSION_STATE_READY) set_state(*s, XR_SESSION_STATE_SYNCHRONIZED);
  s->should_render = s->state == XR_SESSION_STATE_VISIBLE || s->state == XR_SESSION_STATE_FOCUSED;
  state->predictedDisplayTime = s->predicted_display_ns;
  state->predictedDisplayPeriod = s->period_ns;
  state->shouldRender = s->should_render ? XR_TRUE : XR_FALSE;
  s->frame_waited = true;
  ++s->frames_waited;
  return XR_SUCCESS;
}

XrResult BeginFrame(XrSession handle_, const XrFrameBeginInfo* /*info*/) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (!s->frame_waited) return XR_ERROR_CALL_ORDER_INVALID;
  s->frame_waited = false;
  if (s->frame_begun) return XR_FRAME_DISCARDED;  // the previous frame was never ended
  s->frame_begun = true;
  return XR_SUCCESS;
}

XrResult EndFrame(XrSession handle_, const XrFrameEndInfo* info) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || info->type != XR_TYPE_FRAME_END_INFO) return XR_ERROR_VALIDATION_FAILURE;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (!s->frame_begun) return XR_ERROR_CALL_ORDER_INVALID;
  // Strict: the frame is shown at the time xrWaitFrame predicted for it, nothing else.
  if (info->displayTime <= 0 || info->displayTime != s->predicted_display_ns) {
    return XR_ERROR_TIME_INVALID;
  }
  if (info->environmentBlendMode != XR_ENVIRONMENT_BLEND_MODE_OPAQUE) {
    return XR_ERROR_ENVIRONMENT_BLEND_MODE_UNSUPPORTED;
  }
  if (info->layerCount > 1) return XR_ERROR_LAYER_LIMIT_EXCEEDED;
  const XrCompositionLayerProjection* layer = nullptr;
  if (info->layerCount == 1) {
    if (info->layers == nullptr || info->layers[0] == nullptr ||
        info->layers[0]->type != XR_TYPE_COMPOSITION_LAYER_PROJECTION) {
      return XR_ERROR_LAYER_INVALID;
    }
    layer = reinterpret_cast<const XrCompositionLayerProjection*>(info->layers[0]);
    if (const XrResult r = check_layer(*s, *layer); XR_FAILED(r)) return r;
  }
  const Config& config = s->instance->config;
  std::string views = "[";
  if (layer != nullptr) {
    std::vector<std::uint8_t> rgba;
    for (int eye = 0; eye < 2; ++eye) {
      const XrCompositionLayerProjectionView& v = layer->views[eye];
      auto* chain = object<Swapchain>(v.subImage.swapchain);
      if (!read_back(*chain, static_cast<std::uint32_t>(chain->released),
                     v.subImage.imageArrayIndex)) {
        return XR_ERROR_RUNTIME_FAILURE;
      }
      const bool bytes = chain->format != VK_FORMAT_R16G16B16A16_SFLOAT;
      EyeStats stats;
      if (bytes) stats = measure(*chain, v.subImage.imageRect, rgba);
      if (bytes && !config.png_dir.empty()) {
        char name[64];
        std::snprintf(name, sizeof name, "/frame_%05llu_eye%d.png",
                      static_cast<unsigned long long>(s->frames_ended), eye);
        write_png(config.png_dir + name, rgba.data(),
                  static_cast<std::uint32_t>(v.subImage.imageRect.extent.width),
                  static_cast<std::uint32_t>(v.subImage.imageRect.extent.height));
      }
      if (eye > 0) views += ",";
      views += view_json(eye, v, bytes ? &stats : nullptr);
    }
  }
  s->instance->log.write(
      "frame", "\"frame\":" + std::to_string(s->frames_ended) +
                   ",\"display_time_ns\":" + std::to_string(info->displayTime) +
                   ",\"predicted_display_time_ns\":" + std::to_string(s->predicted_display_ns) +
                   ",\"should_render\":" + (s->should_render ? "true" : "false") +
                   ",\"layers\":" + std::to_string(info->layerCount) + ",\"space\":" +
                   std::to_string(layer != nullptr ? object<Space>(layer->space)->type : 0) +
                   ",\"views\":" + views + "]");
  s->frame_begun = false;
  ++s->frames_ended;
  if (s->state == XR_SESSION_STATE_SYNCHRONIZED && !s->exit_requested) {
    set_state(*s, XR_SESSION_STATE_VISIBLE);
    set_state(*s, XR_SESSION_STATE_FOCUSED);
  }
  if (config.lose_after_frames >= 0 && s->instance->sessions_created == 1 &&
      s->frames_ended == static_cast<std::uint64_t>(config.lose_after_frames)) {
    // The headset is unplugged: the session is lost; it is back config.lost_ms later.
    s->loss_pending = true;
    s->instance->headset_back_ns = now_ns() + static_cast<std::int64_t>(config.lost_ms * 1e6);
    s->instance->log.write("session_lost");
    set_state(*s, XR_SESSION_STATE_LOSS_PENDING);
    return XR_SUCCESS;
  }
  if (config.lose_instance_after_frames >= 0 &&
      s->frames_ended == static_cast<std::uint64_t>(config.lose_instance_after_frames)) {
    // The runtime goes away for good.
    XrEventDataBuffer buffer{};
    XrEventDataInstanceLossPending event{};
    event.type = XR_TYPE_EVENT_DATA_INSTANCE_LOSS_PENDING;
    event.lossTime = now_ns();
    std::memcpy(&buffer, &event, sizeof event);
    s->instance->events.push_back(buffer);
    s->instance->lost = true;
    s->instance->log.write("instance_lost");
    return XR_SUCCESS;
  }
  if (config.exit_after_frames >= 0 && !s->exit_requested &&
      s->frames_ended >= static_cast<std::uint64_t>(config.exit_after_frames)) {
    s->exit_requested = true;  // the user ended the session from the headset
    s->instance->log.write("request_exit", "\"by\":\"user\"");
    begin_stopping(*s);
  }
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
