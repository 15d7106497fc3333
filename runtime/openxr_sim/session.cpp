// The session and its state machine (IDLE -> READY -> SYNCHRONIZED -> VISIBLE -> FOCUSED, and
// STOPPING -> IDLE -> EXITING when the application or the "user" asks to exit), its events and
// reference spaces, and the Vulkan objects the runtime keeps on the application's device.

#include <algorithm>
#include <cmath>
#include <cstring>

#include "api.h"

namespace bisturi::xrsim {

namespace {

Session* checked(XrSession handle_) {
  return object<Session>(handle_);
}

const XrGraphicsBindingVulkan2KHR* vulkan_binding(const void* next) {
  for (auto* s = static_cast<const XrBaseInStructure*>(next); s != nullptr; s = s->next) {
    if (s->type == XR_TYPE_GRAPHICS_BINDING_VULKAN2_KHR) {
      return reinterpret_cast<const XrGraphicsBindingVulkan2KHR*>(s);
    }
  }
  return nullptr;
}

void release_vulkan(Session& s) {
  if (s.device == VK_NULL_HANDLE) return;
  if (s.queue != VK_NULL_HANDLE) vkQueueWaitIdle(s.queue);
  if (s.fence != VK_NULL_HANDLE) vkDestroyFence(s.device, s.fence, nullptr);
  if (s.pool != VK_NULL_HANDLE) vkDestroyCommandPool(s.device, s.pool, nullptr);
  s.fence = VK_NULL_HANDLE;
  s.pool = VK_NULL_HANDLE;
}

}  // namespace

void set_state(Session& session, XrSessionState state) {
  session.state = state;
  XrEventDataBuffer buffer{};
  XrEventDataSessionStateChanged event{};
  event.type = XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED;
  event.session = handle<XrSession>(&session);
  event.state = state;
  event.time = now_ns();
  static_assert(sizeof event <= sizeof buffer);
  std::memcpy(&buffer, &event, sizeof event);
  session.instance->events.push_back(buffer);
  session.instance->log.write("state", "\"state\":" + json_string(state_name(state)) +
                                           ",\"frame\":" + std::to_string(session.frames_ended) +
                                           ",\"time_ns\":" + std::to_string(event.time));
}

/// From wherever the session is (running), down to STOPPING, one state at a time as the
/// specification orders them.
void begin_stopping(Session& session) {
  if (session.state == XR_SESSION_STATE_FOCUSED) set_state(session, XR_SESSION_STATE_VISIBLE);
  if (session.state == XR_SESSION_STATE_VISIBLE) set_state(session, XR_SESSION_STATE_SYNCHRONIZED);
  set_state(session, XR_SESSION_STATE_STOPPING);
}

bool run_commands(Session& session, void (*record)(VkCommandBuffer, void*), void* user) {
  VkCommandBufferBeginInfo begin{};
  begin.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_BEGIN_INFO;
  begin.flags = VK_COMMAND_BUFFER_USAGE_ONE_TIME_SUBMIT_BIT;
  if (vkResetCommandBuffer(session.commands, 0) != VK_SUCCESS ||
      vkBeginCommandBuffer(session.commands, &begin) != VK_SUCCESS) {
    return false;
  }
  record(session.commands, user);
  if (vkEndCommandBuffer(session.commands) != VK_SUCCESS) return false;
  VkSubmitInfo submit{};
  submit.sType = VK_STRUCTURE_TYPE_SUBMIT_INFO;
  submit.commandBufferCount = 1;
  submit.pCommandBuffers = &session.commands;
  if (vkQueueSubmit(session.queue, 1, &submit, session.fence) != VK_SUCCESS) return false;
  const bool done =
      vkWaitForFences(session.device, 1, &session.fence, VK_TRUE, UINT64_MAX) == VK_SUCCESS;
  vkResetFences(session.device, 1, &session.fence);
  return done;
}

std::uint32_t memory_type(VkPhysicalDevice physical, std::uint32_t bits,
                          VkMemoryPropertyFlags flags) {
  VkPhysicalDeviceMemoryProperties memory;
  vkGetPhysicalDeviceMemoryProperties(physical, &memory);
  for (std::uint32_t i = 0; i < memory.memoryTypeCount; ++i) {
    if ((bits & (1u << i)) != 0 && (memory.memoryTypes[i].propertyFlags & flags) == flags) return i;
  }
  return UINT32_MAX;
}

XrResult CreateSession(XrInstance instance_handle, const XrSessionCreateInfo* info,
                       XrSession* session_out) {
  Instance* instance = object<Instance>(instance_handle);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || session_out == nullptr || info->type != XR_TYPE_SESSION_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (instance_lost(instance)) return XR_ERROR_INSTANCE_LOST;
  if (info->systemId != 1) return XR_ERROR_SYSTEM_INVALID;
  if (now_ns() < instance->headset_back_ns) return XR_ERROR_FORM_FACTOR_UNAVAILABLE;
  if (!instance->requirements_queried) return XR_ERROR_GRAPHICS_REQUIREMENTS_CALL_MISSING;
  const XrGraphicsBindingVulkan2KHR* binding = vulkan_binding(info->next);
  // XR_KHR_vulkan_enable2: the device must be one made through xrCreateVulkanDeviceKHR.
  if (binding == nullptr || binding->device == VK_NULL_HANDLE ||
      binding->physicalDevice != instance->physical ||
      std::find(instance->devices.begin(), instance->devices.end(), binding->device) ==
          instance->devices.end()) {
    return XR_ERROR_GRAPHICS_DEVICE_INVALID;
  }
  if (instance->session != nullptr) return XR_ERROR_LIMIT_REACHED;

  auto* s = new Session();
  s->instance = instance;
  s->device = binding->device;
  s->queue_family = binding->queueFamilyIndex;
  vkGetDeviceQueue(s->device, binding->queueFamilyIndex, binding->queueIndex, &s->queue);
  VkCommandPoolCreateInfo pool{};
  pool.sType = VK_STRUCTURE_TYPE_COMMAND_POOL_CREATE_INFO;
  pool.flags = VK_COMMAND_POOL_CREATE_RESET_COMMAND_BUFFER_BIT;
  pool.queueFamilyIndex = s->queue_family;
  VkCommandBufferAllocateInfo allocate{};
  allocate.sType = VK_STRUCTURE_TYPE_COMMAND_BUFFER_ALLOCATE_INFO;
  allocate.level = VK_COMMAND_BUFFER_LEVEL_PRIMARY;
  allocate.commandBufferCount = 1;
  VkFenceCreateInfo fence{};
  fence.sType = VK_STRUCTURE_TYPE_FENCE_CREATE_INFO;
  if (vkCreateCommandPool(s->device, &pool, nullptr, &s->pool) != VK_SUCCESS ||
      (allocate.commandPool = s->pool,
       vkAllocateCommandBuffers(s->device, &allocate, &s->commands) != VK_SUCCESS) ||
      vkCreateFence(s->device, &fence, nullptr, &s->fence) != VK_SUCCESS) {
    release_vulkan(*s);
    delete s;
    return XR_ERROR_RUNTIME_FAILURE;
  }
  s->period_ns = static_cast<std::int64_t>(std::llround(1e9 / instance->config.display_hz));
  instance->session = s;
  ++instance->sessions_created;
  track(s);
  instance->log.write("session_created",
                      "\"number\":" + std::to_string(instance->sessions_created));
  set_state(*s, XR_SESSION_STATE_IDLE);
  set_state(*s, XR_SESSION_STATE_READY);  // the headset is worn and ready at once
  *session_out = handle<XrSession>(s);
  return XR_SUCCESS;
}

XrResult DestroySession(XrSession handle_) {
  Session* s = checked(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  while (!s->swapchains.empty())
    destroy_swapchain(s->swapchains.back());
  for (Space* space : s->spaces) {
    untrack(space);
    delete space;
  }
  release_vulkan(*s);
  s->instance->log.write("session_destroyed",
                         "\"frames\":" + std::to_string(s->frames_ended) +
                             ",\"running\":" + (s->running ? "true" : "false"));
  // Events of a destroyed session are dropped (the specification allows it).
  auto& events = s->instance->events;
  events.erase(std::remove_if(events.begin(), events.end(),
                              [&](const XrEventDataBuffer& e) {
                                XrEventDataSessionStateChanged c;
                                std::memcpy(&c, &e, sizeof c);
                                return c.type == XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED &&
                                       c.session == handle_;
                              }),
               events.end());
  for (ActionSet* set : s->instance->action_sets) {
    if (set->attached_to == s) set->attached_to = nullptr;  // free to attach to a new session
  }
  s->instance->session = nullptr;
  untrack(s);
  delete s;
  return XR_SUCCESS;
}

XrResult BeginSession(XrSession handle_, const XrSessionBeginInfo* info) {
  Session* s = checked(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || info->type != XR_TYPE_SESSION_BEGIN_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (info->primaryViewConfigurationType != XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO) {
    return XR_ERROR_VIEW_CONFIGURATION_TYPE_UNSUPPORTED;
  }
  if (s->running) return XR_ERROR_SESSION_RUNNING;
  if (s->state != XR_SESSION_STATE_READY) return XR_ERROR_SESSION_NOT_READY;
  s->running = true;
  s->next_display_ns = 0;
  s->frame_waited = s->frame_begun = false;
  s->instance->log.write("begin_session");
  return XR_SUCCESS;
}

XrResult EndSession(XrSession handle_) {
  Session* s = checked(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  if (s->state != XR_SESSION_STATE_STOPPING) return XR_ERROR_SESSION_NOT_STOPPING;
  s->running = false;
  s->instance->log.write("end_session");
  set_state(*s, XR_SESSION_STATE_IDLE);
  if (s->exit_requested) set_state(*s, XR_SESSION_STATE_EXITING);
  return XR_SUCCESS;
}

XrResult RequestExitSession(XrSession handle_) {
  Session* s = checked(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (instance_lost(s->instance)) return XR_ERROR_INSTANCE_LOST;
  if (s->loss_pending) return XR_ERROR_SESSION_LOST;
  if (!s->running) return XR_ERROR_SESSION_NOT_RUNNING;
  s->instance->log.write("request_exit", "\"by\":\"application\"");
  if (!s->exit_requested) {
    s->exit_requested = true;
    begin_stopping(*s);
  }
  return XR_SUCCESS;
}

XrResult PollEvent(XrInstance instance_handle, XrEventDataBuffer* event) {
  Instance* instance = object<Instance>(instance_handle);
  if (instance == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (event == nullptr || event->type != XR_TYPE_EVENT_DATA_BUFFER) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (instance->events.empty())
    return instance->lost ? XR_ERROR_INSTANCE_LOST : XR_EVENT_UNAVAILABLE;
  *event = instance->events.front();
  instance->events.pop_front();
  return XR_SUCCESS;
}

XrResult EnumerateReferenceSpaces(XrSession handle_, std::uint32_t capacity, std::uint32_t* count,
                                  XrReferenceSpaceType* out) {
  if (checked(handle_) == nullptr) return XR_ERROR_HANDLE_INVALID;
  const XrReferenceSpaceType types[] = {XR_REFERENCE_SPACE_TYPE_VIEW, XR_REFERENCE_SPACE_TYPE_LOCAL,
                                        XR_REFERENCE_SPACE_TYPE_STAGE};
  if (count == nullptr) return XR_ERROR_VALIDATION_FAILURE;
  *count = 3;
  if (capacity == 0) return XR_SUCCESS;
  if (capacity < 3) return XR_ERROR_SIZE_INSUFFICIENT;
  std::copy(std::begin(types), std::end(types), out);
  return XR_SUCCESS;
}

XrResult CreateReferenceSpace(XrSession handle_, const XrReferenceSpaceCreateInfo* info,
                              XrSpace* space) {
  Session* s = checked(handle_);
  if (s == nullptr) return XR_ERROR_HANDLE_INVALID;
  if (info == nullptr || space == nullptr || info->type != XR_TYPE_REFERENCE_SPACE_CREATE_INFO) {
    return XR_ERROR_VALIDATION_FAILURE;
  }
  if (info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_VIEW &&
      info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_LOCAL &&
      info->referenceSpaceType != XR_REFERENCE_SPACE_TYPE_STAGE) {
    return XR_ERROR_REFERENCE_SPACE_UNSUPPORTED;
  }
  const XrQuaternionf& q = info->poseInReferenceSpace.orientation;
  const float norm = q.x * q.x + q.y * q.y + q.z * q.z + q.w * q.w;
  if (std::abs(norm - 1.0f) > 1e-3f) return XR_ERROR_POSE_INVALID;
  auto* created = new Space();
  created->session = s;
  created->type = info->referenceSpaceType;
  s->spaces.push_back(created);
  track(created);
  s->instance->log.write("space", "\"type\":" + std::to_string(info->referenceSpaceType));
  *space = handle<XrSpace>(created);
  return XR_SUCCESS;
}

XrResult DestroySpace(XrSpace handle_) {
  Space* space = object<Space>(handle_);
  if (space == nullptr) return XR_ERROR_HANDLE_INVALID;
  auto& list = space->session->spaces;
  list.erase(std::remove(list.begin(), list.end(), space), list.end());
  untrack(space);
  delete space;
  return XR_SUCCESS;
}

}  // namespace bisturi::xrsim
