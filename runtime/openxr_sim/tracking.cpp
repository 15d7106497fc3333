// Tracking of the simulated headset: a head that moves (a slow sway, turn and nod, as a function
// of time, so every display time has one pose), two eyes with asymmetric fields of view that
// differ per eye, frames whose views are not valid, and xrLocateViews / xrLocateSpace over them.

#include <algorithm>
#include <cmath>

#include <glm/gtc/quaternion.hpp>

#include "api.h"

namespace bisturi::xrsim {

namespace {

constexpr double kTwoPi = 6.283185307179586;

glm::dquat to_glm(const XrQuaternionf& q) {
  return {q.w, q.x, q.y, q.z};
}
XrQuaternionf to_xr(const glm::dquat& q) {
  return {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z),
          static_cast<float>(q.w)};
}
glm::dvec3 to_glm(const XrVector3f& v) {
  return {v.x, v.y, v.z};
}
XrVector3f to_xr(const glm::dvec3& v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}

/// Whether the frame the application last waited for is one whose views are not valid.
bool invalid_now(const Session& s) {
  if (s.frames_waited == 0) return false;
  const auto& list = s.instance->config.invalid_view_frames;
  return std::find(list.begin(), list.end(), s.frames_waited - 1) != list.end();
}

/// A wild pose, as a runtime may leave in a view whose location is not valid.
XrPosef garbage_pose() {
  XrPosef p{};
  p.orientation = {0.9f, 0.1f, -0.3f, 0.2f};  // not even normalized
  p.position = {123.0f, -45.0f, 6789.0f};
  return p;
}

}  // namespace

bool instance_lost(const Instance* instance) {
  return instance != nullptr && instance->lost;
}

XrPosef head_pose(const Instance& instance, std::int64_t time_ns, int view) {
  const Config& c = instance.config;
  const double t = static_cast<double>(time_ns - instance.start_ns) * 1e-9;
  glm::dvec3 position(0.0);
  glm::dquat orientation(1.0, 0.0, 0.0, 0.0);
  if (!c.still_head) {
    position = {0.04 * std::sin(kTwoPi * t / 1.7), 0.015 * std::sin(kTwoPi * t / 2.3),
                0.02 * std::sin(kTwoPi * t / 3.1)};
    const double yaw = 0.25 * std::sin(kTwoPi * t / 2.9);
    const double pitch = -0.15 + 0.1 * std::sin(kTwoPi * t / 2.1);
    orientation =
        glm::angleAxis(yaw, glm::dvec3(0, 1, 0)) * glm::angleAxis(pitch, glm::dvec3(1, 0, 0));
  }
  if (view >= 0) {
    const double side = view == 0 ? -0.5 : 0.5;
    position += orientation * glm::dvec3(side * c.ipd_m, 0.0, 0.0);
  }
  XrPosef pose;
  pose.orientation = to_xr(glm::normalize(orientation));
  pose.position = to_xr(position);
  return pose;
}

XrPosef space_origin(XrReferenceSpaceType type) {
  XrPosef origin{};
  origin.orientation.w = 1.0f;
  if (type == XR_REFERENCE_SPACE_TYPE_STAGE) origin.position.y = -1.6f;  // the floor
  return origin;
}

XrPosef relative_to(const XrPosef& origin, const XrPosef& pose) {
  const glm::dquat inverse = glm::inverse(to_glm(origin.orientation));
  XrPosef out;
  out.orientation = to_xr(glm::normalize(inverse * to_glm(pose.orientation)));
  out.position = to_xr(inverse * (to_glm(pose.position) - to_glm(origin.position)));
  return out;
}

XrResult LocateViews(XrSession handle_, const XrViewLocateInfo* info, XrViewState* state,
                     std::uint32_t capacity, std::uint32_t* count, XrView* views) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || state == nullptr || count == nullptr ||
      info->type != XR_TYPE_VIEW_LOCATE_INFO || state->type != XR_TYPE_VIEW_STATE) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (info->viewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO) {
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  }
  if (info->displayTime <= 0) return XR_ERROR_TIME_INVALID;
  const Space* space = object<Space>(info->space);
  if (space == nullptr || space->session != s) return XR_ERROR_HANDLE_INVALID;
  *count = 2;
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < 2) return XR_ERROR_SIZE_INSUFFICIENT;
  if (views == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  for (std::uint32_t i = 0; i < 2; ++i) {
    if (views[i].type != XR_TYPE_VIEW) return XR_ERROR_VALIDATION_FAILURE;
  }
  const bool valid = !invalid_now(*s);
  state->viewStateFlags =
      valid ? XR_VIEW_STATE_ORIENTATION_VALID_BIT | XR_VIEW_STATE_POSITION_VALID_BIT |
                  XR_VIEW_STATE_ORIENTATION_TRACKED_BIT | XR_VIEW_STATE_POSITION_TRACKED_BIT
            : 0;
  const XrPosef origin = space_origin(space->type);
  std::string logged = "[";
  for (int eye = 0; eye < 2; ++eye) {
    XrView& v = views[eye];
    v.pose = valid ? relative_to(origin, head_pose(*s->instance, info->displayTime, eye))
                   : garbage_pose();
    v.fov = s->instance->config.fov[static_cast<std::size_t>(eye)];
    const float position[3] = {v.pose.position.x, v.pose.position.y, v.pose.position.z};
    const float orientation[4] = {v.pose.orientation.x, v.pose.orientation.y, v.pose.orientation.z,
                                  v.pose.orientation.w};
    const float fov[4] = {v.fov.angleLeft, v.fov.angleRight, v.fov.angleUp, v.fov.angleDown};
    if (eye > 0) logged += ",";
    logged += "{\"position\":" + json_floats(position, 3) +
              ",\"orientation\":" + json_floats(orientation, 4) +
              ",\"fov\":" + json_floats(fov, 4) + "}";
  }
  s->instance->log.write(
      "located", "\"frame\":" + std::to_string(s->frames_waited - 1) +
                     ",\"display_time_ns\":" + std::to_string(info->displayTime) +
                     ",\"space\":" + std::to_string(space->type) +
                     ",\"valid\":" + (valid ? "true" : "false") + ",\"views\":" + logged + "]");
  return XR_SUCCESS;
}

XrResult LocateSpace(XrSpace space_handle, XrSpace base_handle, XrTime time,
                     XrSpaceLocation* location) {
  const Space* space = object<Space>(space_handle);
  const Space* base = object<Space>(base_handle);
  if (space == nullptr || base == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (space->session != base->session) return XR_ERROR_VALIDATION_FAILURE;
  const Session& s = *space->session;
  if (instance_lost(s.instance)) return XR_ERROR_INSTANCE_LOST;
  if (s.loss_pending) return XR_ERROR_SESSION_LOST;
  if (location == nullptr || location->type != XR_TYPE_SPACE_LOCATION) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (time <= 0) return XR_ERROR_TIME_INVALID;
  const auto in_local = [&](const Space& sp) {
    if (sp.action != nullptr) return grip_pose(*s.instance, time);  // a controller's grip
    return sp.type == XR_REFERENCE_SPACE_TYPE_VIEW ? head_pose(*s.instance, time, -1)
                                                   : space_origin(sp.type);
  };
  const auto is_head = [](const Space& sp) {
    return sp.action == nullptr && sp.type == XR_REFERENCE_SPACE_TYPE_VIEW;
  };
  // A controller is located only while it is bound and its input reaches the session.
  const bool hands = (space->action == nullptr || action_space_tracked(*space)) &&
                     (base->action == nullptr || action_space_tracked(*base));
  const bool valid = !((is_head(*space) || is_head(*base)) && invalid_now(s)) && hands;
  location->locationFlags =
      valid ? XR_SPACE_LOCATION_ORIENTATION_VALID_BIT | XR_SPACE_LOCATION_POSITION_VALID_BIT |
                  XR_SPACE_LOCATION_ORIENTATION_TRACKED_BIT | XR_SPACE_LOCATION_POSITION_TRACKED_BIT
            : 0;
  location->pose = valid ? relative_to(in_local(*base), in_local(*space)) : garbage_pose();
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
