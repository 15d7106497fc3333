// The OpenXR sink's controller input: one action set with the right hand's grip pose, trigger
// and vibration, suggested for the Khronos simple controller (every runtime maps it to what the
// headset has), attached in each session; read once per frame at the display time.

#include "openxr_sink_impl.h"

namespace bisturi::render {

namespace {

template <typename T>
T blank(XrStructureType type) {
  T t{};
  t.type = type;
  return t;
}

}  // namespace

void OpenXrSink::Impl::create_input() {
  xr_setup(xrStringToPath(instance, "/user/hand/right", &right_hand), "xrStringToPath");
  auto set_info = blank<XrActionSetCreateInfo>(XR_TYPE_ACTION_SET_CREATE_INFO);
  std::strncpy(set_info.actionSetName, "instrument", XR_MAX_ACTION_SET_NAME_SIZE - 1);
  std::strncpy(set_info.localizedActionSetName, "Instrument",
               XR_MAX_LOCALIZED_ACTION_SET_NAME_SIZE - 1);
  xr_setup(xrCreateActionSet(instance, &set_info, &action_set), "xrCreateActionSet");
  const auto action = [&](const char* name, const char* shown, XrActionType type, XrAction& out) {
    auto info = blank<XrActionCreateInfo>(XR_TYPE_ACTION_CREATE_INFO);
    std::strncpy(info.actionName, name, XR_MAX_ACTION_NAME_SIZE - 1);
    std::strncpy(info.localizedActionName, shown, XR_MAX_LOCALIZED_ACTION_NAME_SIZE - 1);
    info.actionType = type;
    info.countSubactionPaths = 1;
    info.subactionPaths = &right_hand;
    xr_setup(xrCreateAction(action_set, &info, &out), "xrCreateAction");
  };
  action("grip", "Instrument pose", XR_ACTION_TYPE_POSE_INPUT, grip_action);
  action("trigger", "Grasp or cut", XR_ACTION_TYPE_FLOAT_INPUT, trigger_action);
  action("contact", "Contact cue", XR_ACTION_TYPE_VIBRATION_OUTPUT, haptic_action);
  const auto path = [&](const char* text) {
    XrPath p = XR_NULL_PATH;
    xr_setup(xrStringToPath(instance, text, &p), "xrStringToPath");
    return p;
  };
  const XrActionSuggestedBinding bindings[] = {
      {grip_action, path("/user/hand/right/input/grip/pose")},
      {trigger_action, path("/user/hand/right/input/select/click")},
      {haptic_action, path("/user/hand/right/output/haptic")}};
  auto suggested =
      blank<XrInteractionProfileSuggestedBinding>(XR_TYPE_INTERACTION_PROFILE_SUGGESTED_BINDING);
  suggested.interactionProfile = path("/interaction_profiles/khr/simple_controller");
  suggested.countSuggestedBindings = 3;
  suggested.suggestedBindings = bindings;
  xr_setup(xrSuggestInteractionProfileBindings(instance, &suggested),
           "xrSuggestInteractionProfileBindings");
}

void OpenXrSink::Impl::attach_input() {
  auto attach = blank<XrSessionActionSetsAttachInfo>(XR_TYPE_SESSION_ACTION_SETS_ATTACH_INFO);
  attach.countActionSets = 1;
  attach.actionSets = &action_set;
  xr_setup(xrAttachSessionActionSets(session, &attach), "xrAttachSessionActionSets");
  auto space_info = blank<XrActionSpaceCreateInfo>(XR_TYPE_ACTION_SPACE_CREATE_INFO);
  space_info.action = grip_action;
  space_info.subactionPath = right_hand;
  space_info.poseInActionSpace.orientation.w = 1.0f;
  xr_setup(xrCreateActionSpace(session, &space_info, &grip_space), "xrCreateActionSpace");
}

ControllerState OpenXrSink::Impl::read_controller(XrTime display_time) {
  ControllerState c;
  XrActiveActionSet active{action_set, XR_NULL_PATH};
  auto sync = blank<XrActionsSyncInfo>(XR_TYPE_ACTIONS_SYNC_INFO);
  sync.countActiveActionSets = 1;
  sync.activeActionSets = &active;
  const XrResult synced = xrSyncActions(session, &sync);
  if (!xr_frame(synced, "xrSyncActions") || synced == XR_SESSION_NOT_FOCUSED) return c;
  auto get = blank<XrActionStateGetInfo>(XR_TYPE_ACTION_STATE_GET_INFO);
  get.subactionPath = right_hand;
  get.action = grip_action;
  auto pose = blank<XrActionStatePose>(XR_TYPE_ACTION_STATE_POSE);
  if (!xr_frame(xrGetActionStatePose(session, &get, &pose), "xrGetActionStatePose")) return c;
  get.action = trigger_action;
  auto trigger = blank<XrActionStateFloat>(XR_TYPE_ACTION_STATE_FLOAT);
  if (!xr_frame(xrGetActionStateFloat(session, &get, &trigger), "xrGetActionStateFloat")) {
    return c;
  }
  if (pose.isActive != XR_TRUE) return c;
  auto location = blank<XrSpaceLocation>(XR_TYPE_SPACE_LOCATION);
  c.sample_time = PoseClock::now();
  if (!xr_frame(xrLocateSpace(grip_space, space, display_time, &location), "xrLocateSpace")) {
    return c;
  }
  const bool located = (location.locationFlags & XR_SPACE_LOCATION_POSITION_VALID_BIT) != 0 &&
                       (location.locationFlags & XR_SPACE_LOCATION_ORIENTATION_VALID_BIT) != 0;
  if (!located) return c;  // never a pose the runtime did not vouch for
  const XrPosef& p = location.pose;
  c.active = true;
  c.grip_mm = world_position({p.position.x, p.position.y, p.position.z});
  c.grip_orientation =
      world_orientation({p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z});
  c.trigger = trigger.isActive == XR_TRUE ? std::clamp(trigger.currentState, 0.0f, 1.0f) : 0.0f;
  return c;
}

bool OpenXrSink::Impl::vibrate(float amplitude, double duration_s) {
  if (!(amplitude >= 0.0f && amplitude <= 1.0f)) {
    throw RenderError("a vibration amplitude must be between 0 and 1, not " +
                      std::to_string(amplitude));
  }
  if (!options.controller || session == XR_NULL_HANDLE || !running) return false;
  auto info = blank<XrHapticActionInfo>(XR_TYPE_HAPTIC_ACTION_INFO);
  info.action = haptic_action;
  info.subactionPath = right_hand;
  XrHapticVibration v{};
  v.type = XR_TYPE_HAPTIC_VIBRATION;
  v.amplitude = amplitude;
  v.frequency = XR_FREQUENCY_UNSPECIFIED;
  v.duration =
      duration_s > 0.0 ? static_cast<XrDuration>(duration_s * 1e9) : XR_MIN_HAPTIC_DURATION;
  const XrResult r =
      xrApplyHapticFeedback(session, &info, reinterpret_cast<const XrHapticBaseHeader*>(&v));
  if (!xr_frame(r, "xrApplyHapticFeedback") || r == XR_SESSION_NOT_FOCUSED) return false;
  ++stats.vibrations;
  return true;
}

}  // namespace bisturi::render
