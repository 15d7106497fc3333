// Input of the simulated headset: paths, action sets and actions, suggested bindings for the one
// interaction profile it has (the Khronos simple controller), attaching, syncing, the action
// states, action spaces for the controllers' grips, and vibration, each logged. Strict as the
// specification: malformed paths, bindings the profile has not, type mismatches, late
// suggestions, states asked before a sync are refused with the specified errors.

#include <algorithm>
#include <cmath>
#include <cstring>

#include <glm/gtc/quaternion.hpp>

#include "api.h"

namespace bisturi::xrsim {

namespace {

constexpr const char* kProfile = "/interaction_profiles/khr/simple_controller";
constexpr double kTwoPi = 6.283185307179586;

bool well_formed(const std::string& p) {
  if (p.size() < 2 || p[0] != '/' || p.back() == '/' || p.find("//") != std::string::npos) {
    return false;
  }
  return std::all_of(p.begin(), p.end(), [](char c) {
    return (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '-' || c == '_' || c == '.' ||
           c == '/';
  });
}

const std::string* path_text(const Instance& instance, XrPath path) {
  if (path == XR_NULL_PATH || path > instance.paths.size()) return nullptr;
  return &instance.paths[path - 1];
}

/// Whether `binding` (a path of the simple controller) takes an action of `type`.
bool binding_fits(const std::string& binding, XrActionType type) {
  for (const char* hand : {"/user/hand/left", "/user/hand/right"}) {
    const std::string h = hand;
    if (binding == h + "/input/select/click" || binding == h + "/input/menu/click") {
      return type == XR_ACTION_TYPE_BOOLEAN_INPUT || type == XR_ACTION_TYPE_FLOAT_INPUT;
    }
    if (binding == h + "/input/grip/pose" || binding == h + "/input/aim/pose") {
      return type == XR_ACTION_TYPE_POSE_INPUT;
    }
    if (binding == h + "/output/haptic") return type == XR_ACTION_TYPE_VIBRATION_OUTPUT;
  }
  return false;
}

/// Whether `action` is bound on the hand of `subaction` (XR_NULL_PATH: on any hand).
bool bound(const Action& action, const Instance& instance, XrPath subaction) {
  const std::string* hand = path_text(instance, subaction);
  return std::any_of(action.bindings.begin(), action.bindings.end(), [&](const std::string& b) {
    return hand == nullptr || b.rfind(*hand + "/", 0) == 0;
  });
}

bool right_hand(const Instance& instance, XrPath subaction) {
  const std::string* hand = path_text(instance, subaction);
  return hand == nullptr || *hand == "/user/hand/right";
}

/// The checks every action-state call makes: the action, its set attached to this session, the
/// subaction path one of the action's.
XrResult check_action(const Session& s, XrAction handle_, XrPath subaction, XrActionType type,
                      const Action** out) {
  const Action* action = object<Action>(handle_);
  if (action == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (action->type != type) return XR_ERROR_ACTION_TYPE_MISMATCH;
  if (action->set->attached_to != &s) return XR_ERROR_ACTIONSET_NOT_ATTACHED;
  if (subaction != XR_NULL_PATH && std::find(action->subactions.begin(), action->subactions.end(),
                                             subaction) == action->subactions.end()) {
    return XR_ERROR_PATH_UNSUPPORTED;
  }
  *out = action;
  return XR_SUCCESS;
}

bool trigger_held(const Session& s) {
  const Config& c = s.instance->config;
  const auto frame = static_cast<std::int64_t>(s.synced_frame);
  return c.trigger_from >= 0 && frame >= c.trigger_from && frame <= c.trigger_to;
}

}  // namespace

XrPosef grip_pose(const Instance& instance, std::int64_t time_ns) {
  const double t = static_cast<double>(time_ns - instance.start_ns) * 1e-9;
  XrPosef pose;
  const glm::dquat q = glm::angleAxis(-0.6 + 0.1 * std::sin(kTwoPi * t / 2.3), glm::dvec3(1, 0, 0));
  pose.orientation = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z),
                      static_cast<float>(q.w)};
  pose.position = {static_cast<float>(0.18 + 0.03 * std::sin(kTwoPi * t / 1.3)), -0.30f,
                   static_cast<float>(-0.35 + 0.04 * std::sin(kTwoPi * t / 1.9))};
  return pose;
}

bool action_space_tracked(const Space& space) {
  const Session& s = *space.session;
  return space.action != nullptr && s.synced && s.state == XR_SESSION_STATE_FOCUSED &&
         space.action->set->attached_to == &s &&
         bound(*space.action, *s.instance, space.subaction) &&
         right_hand(*s.instance, space.subaction);
}

void destroy_action_sets(Instance& instance) {
  for (ActionSet* set : instance.action_sets) {
    for (Action* a : set->actions) {
      untrack(a);
      delete a;
    }
    untrack(set);
    delete set;
  }
  instance.action_sets.clear();
}

XrResult StringToPath(XrInstance handle_, const char* text, XrPath* path) {
  Instance* instance = object<Instance>(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (text == nullptr || path == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  const std::string p = text;
  if (!well_formed(p)) return XR_ERROR_PATH_FORMAT_INVALID;
  const auto it = std::find(instance->paths.begin(), instance->paths.end(), p);
  if (it == instance->paths.end()) instance->paths.push_back(p);
  *path = static_cast<XrPath>(std::find(instance->paths.begin(), instance->paths.end(), p) -
                              instance->paths.begin() + 1);
  return XR_SUCCESS;
}

XrResult PathToString(XrInstance handle_, XrPath path, std::uint32_t capacity, std::uint32_t* count,
                      char* buffer) {
  Instance* instance = object<Instance>(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  const std::string* text = path_text(*instance, path);
  if (text == nullptr) return XR_ERROR_PATH_INVALID;
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *count = static_cast<std::uint32_t>(text->size() + 1);
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < *count) return XR_ERROR_SIZE_INSUFFICIENT;
  std::memcpy(buffer, text->c_str(), *count);
  return XR_SUCCESS;
}

XrResult CreateActionSet(XrInstance handle_, const XrActionSetCreateInfo* info, XrActionSet* out) {
  Instance* instance = object<Instance>(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (info == nullptr || out == nullptr || info->type != XR_TYPE_ACTION_SET_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const std::string name(info->actionSetName,
                         strnlen(info->actionSetName, sizeof info->actionSetName));
  if (name.empty() || !well_formed("/" + name) || name.find('/') != std::string::npos) {
    return XR_ERROR_PATH_FORMAT_INVALID;
  }
  if (info->localizedActionSetName[0] == '\0') return XR_ERROR_LOCALIZED_NAME_INVALID;
  for (const ActionSet* s : instance->action_sets) {
    if (s->name == name) return XR_ERROR_NAME_DUPLICATED;
  }
  auto* set = new ActionSet();
  set->instance = instance;
  set->name = name;
  instance->action_sets.push_back(set);
  track(set);
  *out = handle<XrActionSet>(set);
  return XR_SUCCESS;
}

XrResult DestroyActionSet(XrActionSet handle_) {
  ActionSet* set = object<ActionSet>(handle_);
  if (set == nullptr) return XR_ERROR_HANDLE_INVALID;
  auto& sets = set->instance->action_sets;
  sets.erase(std::remove(sets.begin(), sets.end(), set), sets.end());
  for (Action* a : set->actions) {
    untrack(a);
    delete a;
  }
  untrack(set);
  delete set;
  return XR_SUCCESS;
}

XrResult CreateAction(XrActionSet handle_, const XrActionCreateInfo* info, XrAction* out) {
  ActionSet* set = object<ActionSet>(handle_);
  if (set == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (set->ever_attached) return XR_ERROR_ACTIONSETS_ALREADY_ATTACHED;
  if (info == nullptr || out == nullptr || info->type != XR_TYPE_ACTION_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const std::string name(info->actionName, strnlen(info->actionName, sizeof info->actionName));
  if (name.empty() || !well_formed("/" + name) || name.find('/') != std::string::npos) {
    return XR_ERROR_PATH_FORMAT_INVALID;
  }
  if (info->localizedActionName[0] == '\0') return XR_ERROR_LOCALIZED_NAME_INVALID;
  for (const Action* a : set->actions) {
    if (a->name == name) return XR_ERROR_NAME_DUPLICATED;
  }
  auto* action = new Action();
  action->set = set;
  action->name = name;
  action->type = info->actionType;
  for (std::uint32_t i = 0; i < info->countSubactionPaths; ++i) {
    const std::string* p = path_text(*set->instance, info->subactionPaths[i]);
    if (p == nullptr || (*p != "/user/hand/left" && *p != "/user/hand/right" &&
                         *p != "/user/head" && *p != "/user/gamepad")) {
      delete action;
      return XR_ERROR_PATH_UNSUPPORTED;
    }
    action->subactions.push_back(info->subactionPaths[i]);
  }
  set->actions.push_back(action);
  track(action);
  *out = handle<XrAction>(action);
  return XR_SUCCESS;
}

XrResult DestroyAction(XrAction handle_) {
  Action* action = object<Action>(handle_);
  if (action == nullptr) return XR_ERROR_HANDLE_INVALID;
  auto& list = action->set->actions;
  list.erase(std::remove(list.begin(), list.end(), action), list.end());
  untrack(action);
  delete action;
  return XR_SUCCESS;
}

XrResult SuggestInteractionProfileBindings(XrInstance handle_,
                                           const XrInteractionProfileSuggestedBinding* info) {
  Instance* instance = object<Instance>(handle_);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (info == nullptr || info->type != XR_TYPE_INTERACTION_PROFILE_SUGGESTED_BINDING ||
      info->countSuggestedBindings == 0 || info->suggestedBindings == nullptr) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const std::string* profile = path_text(*instance, info->interactionProfile);
  if (profile == nullptr) return XR_ERROR_PATH_INVALID;
  if (*profile != kProfile) return XR_ERROR_PATH_UNSUPPORTED;  // the one profile it has
  std::vector<std::pair<Action*, std::string>> bindings;
  for (std::uint32_t i = 0; i < info->countSuggestedBindings; ++i) {
    Action* action = object<Action>(info->suggestedBindings[i].action);
    if (action == nullptr) return XR_ERROR_HANDLE_INVALID;
    if (action->set->ever_attached) return XR_ERROR_ACTIONSETS_ALREADY_ATTACHED;
    const std::string* binding = path_text(*instance, info->suggestedBindings[i].binding);
    if (binding == nullptr) return XR_ERROR_PATH_INVALID;
    if (!binding_fits(*binding, action->type)) return XR_ERROR_PATH_UNSUPPORTED;
    bindings.emplace_back(action, *binding);
  }
  // A suggestion for the profile replaces the previous one.
  for (ActionSet* set : instance->action_sets) {
    for (Action* a : set->actions)
      a->bindings.clear();
  }
  for (auto& [action, binding] : bindings)
    action->bindings.push_back(binding);
  instance->log.write("bindings", "\"count\":" + std::to_string(bindings.size()));
  return XR_SUCCESS;
}

XrResult AttachSessionActionSets(XrSession handle_, const XrSessionActionSetsAttachInfo* info) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || info->type != XR_TYPE_SESSION_ACTION_SETS_ATTACH_INFO ||
      info->countActionSets == 0 || info->actionSets == nullptr) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (s->actions_attached) return XR_ERROR_ACTIONSETS_ALREADY_ATTACHED;
  for (std::uint32_t i = 0; i < info->countActionSets; ++i) {
    ActionSet* set = object<ActionSet>(info->actionSets[i]);
    if (set == nullptr) return XR_ERROR_HANDLE_INVALID;
    // One live session at a time here (the runtime has one session).
    if (set->attached_to != nullptr && set->attached_to != s) {
      return XR_ERROR_ACTIONSETS_ALREADY_ATTACHED;
    }
  }
  for (std::uint32_t i = 0; i < info->countActionSets; ++i) {
    ActionSet* set = object<ActionSet>(info->actionSets[i]);
    set->attached_to = s;
    set->ever_attached = true;
  }
  s->actions_attached = true;
  s->instance->log.write("attach", "\"sets\":" + std::to_string(info->countActionSets));
  return XR_SUCCESS;
}

XrResult CreateActionSpace(XrSession handle_, const XrActionSpaceCreateInfo* info, XrSpace* space) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (info == nullptr || space == nullptr || info->type != XR_TYPE_ACTION_SPACE_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const Action* action = object<Action>(info->action);
  if (action == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (action->type != XR_ACTION_TYPE_POSE_INPUT) return XR_ERROR_ACTION_TYPE_MISMATCH;
  if (info->subactionPath != XR_NULL_PATH &&
      std::find(action->subactions.begin(), action->subactions.end(), info->subactionPath) ==
          action->subactions.end()) {
    return XR_ERROR_PATH_UNSUPPORTED;
  }
  const XrQuaternionf& q = info->poseInActionSpace.orientation;
  if (std::abs(q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w - 1.0f) > 1e-3f) {
    return XR_ERROR_POSE_INVALID;
  }
  auto* created = new Space();
  created->session = s;
  created->action = action;
  created->subaction = info->subactionPath;
  s->spaces.push_back(created);
  track(created);
  *space = handle<XrSpace>(created);
  return XR_SUCCESS;
}

XrResult SyncActions(XrSession handle_, const XrActionsSyncInfo* info) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || info->type != XR_TYPE_ACTIONS_SYNC_INFO ||
      (info->countActiveActionSets > 0 && info->activeActionSets == nullptr)) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  for (std::uint32_t i = 0; i < info->countActiveActionSets; ++i) {
    const ActionSet* set = object<ActionSet>(info->activeActionSets[i].actionSet);
    if (set == nullptr) return XR_ERROR_HANDLE_INVALID;
    if (set->attached_to != s) return XR_ERROR_ACTIONSET_NOT_ATTACHED;
  }
  if (s->state != XR_SESSION_STATE_FOCUSED) {
    s->synced = false;  // input goes only to the focused application
    return XR_SESSION_NOT_FOCUSED;
  }
  s->synced = true;
  s->synced_frame = s->frames_waited > 0 ? s->frames_waited - 1 : 0;
  return XR_SUCCESS;
}

/// What every xrGetActionState* checks first: the session, its instance, the structures' types
/// and the action (of `action_type`, for that subaction path).
template <typename State>
XrResult action_state_call(XrSession handle, const XrActionStateGetInfo* info, State* state,
                           XrStructureType state_type, XrActionType action_type, Session** session,
                           const Action** action) {
  Session* s = object<Session>(handle);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (info == nullptr || state == nullptr || info->type != XR_TYPE_ACTION_STATE_GET_INFO ||
      state->type != state_type) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  *session = s;
  return check_action(*s, info->action, info->subactionPath, action_type, action);
}

XrResult GetActionStateFloat(XrSession handle_, const XrActionStateGetInfo* info,
                             XrActionStateFloat* state) {
  Session* s = nullptr;
  const Action* action = nullptr;
  if (const XrResult r = action_state_call(handle_, info, state, XR_TYPE_ACTION_STATE_FLOAT,
                                           XR_ACTION_TYPE_FLOAT_INPUT, &s, &action);
      XR_FAILED(r)) {
    return r;
  }
  const bool active = s->synced && bound(*action, *s->instance, info->subactionPath);
  state->isActive = active ? XR_TRUE : XR_FALSE;
  state->currentState =
      active && right_hand(*s->instance, info->subactionPath) && trigger_held(*s) ? 1.0f : 0.0f;
  state->changedSinceLastSync = XR_FALSE;
  state->lastChangeTime = 0;
  return XR_SUCCESS;
}

XrResult GetActionStatePose(XrSession handle_, const XrActionStateGetInfo* info,
                            XrActionStatePose* state) {
  Session* s = nullptr;
  const Action* action = nullptr;
  if (const XrResult r = action_state_call(handle_, info, state, XR_TYPE_ACTION_STATE_POSE,
                                           XR_ACTION_TYPE_POSE_INPUT, &s, &action);
      XR_FAILED(r)) {
    return r;
  }
  state->isActive =
      s->synced && bound(*action, *s->instance, info->subactionPath) ? XR_TRUE : XR_FALSE;
  return XR_SUCCESS;
}

XrResult ApplyHapticFeedback(XrSession handle_, const XrHapticActionInfo* info,
                             const XrHapticBaseHeader* feedback) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info == nullptr || feedback == nullptr || info->type != XR_TYPE_HAPTIC_ACTION_INFO ||
      feedback->type != XR_TYPE_HAPTIC_VIBRATION) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const Action* action = nullptr;
  if (const XrResult r = check_action(*s, info->action, info->subactionPath,
                                      XR_ACTION_TYPE_VIBRATION_OUTPUT, &action);
      XR_FAILED(r)) {
    return r;
  }
  const auto& v = *reinterpret_cast<const XrHapticVibration*>(feedback);
  if (!(v.amplitude >= 0.0f && v.amplitude <= 1.0f) || !std::isfinite(v.frequency) ||
      v.frequency < 0.0f || (v.duration <= 0 && v.duration != XR_MIN_HAPTIC_DURATION)) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (s->state != XR_SESSION_STATE_FOCUSED) return XR_SESSION_NOT_FOCUSED;
  char fields[160];
  std::snprintf(fields, sizeof fields,
                "\"frame\":%llu,\"amplitude\":%.6g,\"duration_ns\":%lld,\"frequency_hz\":%.6g",
                static_cast<unsigned long long>(s->frames_waited > 0 ? s->frames_waited - 1 : 0),
                static_cast<double>(v.amplitude), static_cast<long long>(v.duration),
                static_cast<double>(v.frequency));
  s->instance->log.write("haptic", fields);
  return XR_SUCCESS;
}

XrResult StopHapticFeedback(XrSession handle_, const XrHapticActionInfo* info) {
  Session* s = object<Session>(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || info->type != XR_TYPE_HAPTIC_ACTION_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  const Action* action = nullptr;
  if (const XrResult r = check_action(*s, info->action, info->subactionPath,
                                      XR_ACTION_TYPE_VIBRATION_OUTPUT, &action);
      XR_FAILED(r)) {
    return r;
  }
  s->instance->log.write("haptic_stop");
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
