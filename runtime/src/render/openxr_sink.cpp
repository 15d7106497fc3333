// The OpenXR sink: instance, system, session and its state machine, the frame loop (see
// openxr_sink.h); its Vulkan side is in openxr_sink_vulkan.cpp.

#include "bisturi/runtime/render/openxr_sink.h"

#include "openxr_sink_impl.h"

namespace bisturi::render {

namespace xr_detail {

std::string xr_result(XrInstance instance, XrResult result) {
  char text[XR_MAX_RESULT_STRING_SIZE] = {};
  if (instance != XR_NULL_HANDLE && xrResultToString(instance, result, text) == XR_SUCCESS) {
    return text;
  }
  switch (result) {
    case XR_ERROR_RUNTIME_UNAVAILABLE:
      return "XR_ERROR_RUNTIME_UNAVAILABLE";
    case XR_ERROR_RUNTIME_FAILURE:
      return "XR_ERROR_RUNTIME_FAILURE";
    case XR_ERROR_INSTANCE_LOST:
      return "XR_ERROR_INSTANCE_LOST";
    case XR_ERROR_FORM_FACTOR_UNAVAILABLE:
      return "XR_ERROR_FORM_FACTOR_UNAVAILABLE";
    case XR_ERROR_FORM_FACTOR_UNSUPPORTED:
      return "XR_ERROR_FORM_FACTOR_UNSUPPORTED";
    case XR_ERROR_EXTENSION_NOT_PRESENT:
      return "XR_ERROR_EXTENSION_NOT_PRESENT";
    default:
      return "XrResult " + std::to_string(static_cast<int>(result));
  }
}

}  // namespace xr_detail

namespace {

/// The loader prints its errors to stderr unless XR_LOADER_DEBUG says otherwise, which on every
/// machine without a runtime repeats, in ten lines, what XrUnavailable already says. It reads the
/// variable once, at its first call: quiet it then, unless the user set it (XR_LOADER_DEBUG=error
/// or =all brings the loader's own diagnosis back).
void quiet_loader() {
  static std::once_flag once;
  std::call_once(once, [] { setenv("XR_LOADER_DEBUG", "none", 0); });
}

/// Why the loader found no runtime, as far as can be told from outside it.
std::string missing_runtime_reason() {
  const char* named = std::getenv("XR_RUNTIME_JSON");
  if (named != nullptr && *named != '\0') {
    std::error_code error;
    if (!std::filesystem::exists(named, error)) {
      return std::string("XR_RUNTIME_JSON names ") + named + ", which does not exist";
    }
    return std::string("the runtime that XR_RUNTIME_JSON names (") + named + ") did not load";
  }
  return "none is installed (no active_runtime.json), and XR_RUNTIME_JSON does not name one";
}

const char* state_name(XrSessionState state) {
  switch (state) {
    case XR_SESSION_STATE_IDLE:
      return "IDLE";
    case XR_SESSION_STATE_READY:
      return "READY";
    case XR_SESSION_STATE_SYNCHRONIZED:
      return "SYNCHRONIZED";
    case XR_SESSION_STATE_VISIBLE:
      return "VISIBLE";
    case XR_SESSION_STATE_FOCUSED:
      return "FOCUSED";
    case XR_SESSION_STATE_STOPPING:
      return "STOPPING";
    case XR_SESSION_STATE_LOSS_PENDING:
      return "LOSS_PENDING";
    case XR_SESSION_STATE_EXITING:
      return "EXITING";
    default:
      return "UNKNOWN";
  }
}

/// World (LPS millimetres) to OpenXR LOCAL (metres, y up): a -90 degree turn about x, so that
/// superior is up and anterior is +z (see openxr_sink.h).
XrPosef xr_pose(const glm::dvec3& position_mm, const glm::dquat& orientation) {
  const double h = std::sqrt(0.5);
  const glm::dquat world_to_xr(h, -h, 0.0, 0.0);  // (w, x, y, z)
  const glm::dquat q = glm::normalize(world_to_xr * orientation);
  XrPosef pose;
  pose.orientation = {static_cast<float>(q.x), static_cast<float>(q.y), static_cast<float>(q.z),
                      static_cast<float>(q.w)};
  pose.position = {static_cast<float>(position_mm.x / 1000.0),
                   static_cast<float>(position_mm.z / 1000.0),
                   static_cast<float>(-position_mm.y / 1000.0)};
  return pose;
}

}  // namespace

void OpenXrSink::Impl::create_instance() {
  quiet_loader();
  // The renderer's frames reach the headset through Vulkan: the runtime must offer
  // XR_KHR_vulkan_enable2.
  std::uint32_t count = 0;
  XrResult r = xrEnumerateInstanceExtensionProperties(nullptr, 0, &count, nullptr);
  if (XR_FAILED(r)) {
    throw XrUnavailable("no OpenXR runtime is available (" + xr_result(XR_NULL_HANDLE, r) +
                        "): " + missing_runtime_reason() + kFallback);
  }
  XrExtensionProperties blank_extension{};
  blank_extension.type = XR_TYPE_EXTENSION_PROPERTIES;
  std::vector<XrExtensionProperties> extensions(count, blank_extension);
  xrEnumerateInstanceExtensionProperties(nullptr, count, &count, extensions.data());
  bool vulkan = false;
  for (const XrExtensionProperties& e : extensions) {
    vulkan = vulkan || std::strcmp(e.extensionName, kVulkanExtension) == 0;
  }
  if (!vulkan) {
    throw XrUnavailable("the OpenXR runtime does not offer " + std::string(kVulkanExtension) +
                        kFallback);
  }
  XrInstanceCreateInfo info{};
  info.type = XR_TYPE_INSTANCE_CREATE_INFO;
  std::strncpy(info.applicationInfo.applicationName, options.application_name.c_str(),
               XR_MAX_APPLICATION_NAME_SIZE - 1);
  std::strncpy(info.applicationInfo.engineName, "bisturi", XR_MAX_ENGINE_NAME_SIZE - 1);
  info.applicationInfo.apiVersion = XR_CURRENT_API_VERSION;
  const char* enabled[] = {kVulkanExtension};
  info.enabledExtensionCount = 1;
  info.enabledExtensionNames = enabled;
  r = xrCreateInstance(&info, &instance);
  if (XR_FAILED(r)) {
    instance = XR_NULL_HANDLE;
    throw XrUnavailable("no OpenXR runtime is available (xrCreateInstance: " +
                        xr_result(XR_NULL_HANDLE, r) + ")" + kFallback);
  }
  XrInstanceProperties props{};
  props.type = XR_TYPE_INSTANCE_PROPERTIES;
  if (XR_SUCCEEDED(xrGetInstanceProperties(instance, &props))) runtime = props.runtimeName;
  const auto load = [&](const char* name, auto& function) {
    PFN_xrVoidFunction f = nullptr;
    xr_setup(xrGetInstanceProcAddr(instance, name, &f), name);
    function = reinterpret_cast<std::remove_reference_t<decltype(function)>>(f);
  };
  load("xrGetVulkanGraphicsRequirements2KHR", get_requirements);
  load("xrCreateVulkanInstanceKHR", create_vk_instance);
  load("xrGetVulkanGraphicsDevice2KHR", get_vk_device);
  load("xrCreateVulkanDeviceKHR", create_vk_device);
}

void OpenXrSink::Impl::describe_system() {
  XrSystemGetInfo info{};
  info.type = XR_TYPE_SYSTEM_GET_INFO;
  info.formFactor = XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY;
  const XrResult r = xrGetSystem(instance, &info, &system);
  if (XR_FAILED(r)) {
    throw XrUnavailable("the OpenXR runtime " + runtime + " has no headset (" +
                        xr_result(instance, r) + ")" + kFallback);
  }
  std::uint32_t views = 0;
  xr_setup(xrEnumerateViewConfigurationViews(
               instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &views, nullptr),
           "xrEnumerateViewConfigurationViews");
  if (views != 2) {
    throw XrUnavailable("the OpenXR runtime " + runtime + " offers " + std::to_string(views) +
                        " views for a stereo headset, not 2" + kFallback);
  }
  XrViewConfigurationView blank{};
  blank.type = XR_TYPE_VIEW_CONFIGURATION_VIEW;
  std::vector<XrViewConfigurationView> config(views, blank);
  xr_setup(
      xrEnumerateViewConfigurationViews(instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO,
                                        views, &views, config.data()),
      "xrEnumerateViewConfigurationViews");
  headset.eye_width = config[0].recommendedImageRectWidth;
  headset.eye_height = config[0].recommendedImageRectHeight;
  max_width = std::min(config[0].maxImageRectWidth, config[1].maxImageRectWidth);
  max_height = std::min(config[0].maxImageRectHeight, config[1].maxImageRectHeight);
  // The frames are opaque images: the headset must show them as they are.
  std::uint32_t modes = 0;
  xr_setup(xrEnumerateEnvironmentBlendModes(
               instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &modes, nullptr),
           "xrEnumerateEnvironmentBlendModes");
  std::vector<XrEnvironmentBlendMode> mode(modes);
  xr_setup(
      xrEnumerateEnvironmentBlendModes(instance, system, XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO,
                                       modes, &modes, mode.data()),
      "xrEnumerateEnvironmentBlendModes");
  if (std::find(mode.begin(), mode.end(), XR_ENVIRONMENT_BLEND_MODE_OPAQUE) == mode.end()) {
    throw XrUnavailable("the OpenXR runtime " + runtime +
                        " has no opaque blend mode for the stereo view" + kFallback);
  }
}

void OpenXrSink::Impl::create_session() {
  XrGraphicsBindingVulkan2KHR binding{};
  binding.type = XR_TYPE_GRAPHICS_BINDING_VULKAN2_KHR;
  binding.instance = vk_instance;
  binding.physicalDevice = physical;
  binding.device = device;
  binding.queueFamilyIndex = queue_family;
  binding.queueIndex = 0;
  XrSessionCreateInfo info{};
  info.type = XR_TYPE_SESSION_CREATE_INFO;
  info.next = &binding;
  info.systemId = system;
  xr_setup(xrCreateSession(instance, &info, &session), "xrCreateSession");

  XrReferenceSpaceType type = XR_REFERENCE_SPACE_TYPE_LOCAL;
  if (options.stage_space) {
    std::uint32_t count = 0;
    xr_setup(xrEnumerateReferenceSpaces(session, 0, &count, nullptr), "xrEnumerateReferenceSpaces");
    std::vector<XrReferenceSpaceType> spaces(count);
    xr_setup(xrEnumerateReferenceSpaces(session, count, &count, spaces.data()),
             "xrEnumerateReferenceSpaces");
    if (std::find(spaces.begin(), spaces.end(), XR_REFERENCE_SPACE_TYPE_STAGE) != spaces.end()) {
      type = XR_REFERENCE_SPACE_TYPE_STAGE;
    }
  }
  XrReferenceSpaceCreateInfo space_info{};
  space_info.type = XR_TYPE_REFERENCE_SPACE_CREATE_INFO;
  space_info.referenceSpaceType = type;
  space_info.poseInReferenceSpace.orientation.w = 1.0f;
  xr_setup(xrCreateReferenceSpace(session, &space_info, &space), "xrCreateReferenceSpace");
}

void OpenXrSink::Impl::choose_format() {
  std::uint32_t count = 0;
  xr_setup(xrEnumerateSwapchainFormats(session, 0, &count, nullptr), "xrEnumerateSwapchainFormats");
  std::vector<std::int64_t> formats(count);
  xr_setup(xrEnumerateSwapchainFormats(session, count, &count, formats.data()),
           "xrEnumerateSwapchainFormats");
  // The frames are sRGB-encoded RGBA8 bytes: copied as they are into an sRGB image they mean the
  // same colours. RGBA first (a plain copy), BGRA second (swizzled while staging).
  for (const VkFormat wanted : {VK_FORMAT_R8G8B8A8_SRGB, VK_FORMAT_B8G8R8A8_SRGB}) {
    if (std::find(formats.begin(), formats.end(), wanted) != formats.end()) {
      format = wanted;
      bgra = wanted == VK_FORMAT_B8G8R8A8_SRGB;
      return;
    }
  }
  std::string offered;
  for (const std::int64_t f : formats)
    offered += (offered.empty() ? "" : ", ") + std::to_string(f);
  throw XrUnavailable("the OpenXR runtime " + runtime +
                      " offers no sRGB RGBA8 swapchain format (VK_FORMAT_R8G8B8A8_SRGB or "
                      "VK_FORMAT_B8G8R8A8_SRGB); it offers VkFormat " +
                      (offered.empty() ? std::string("none") : offered) + kFallback);
}

void OpenXrSink::Impl::stop(std::string reason) {
  if (!stopped) stop_reason = std::move(reason);
  stopped = true;
}

void OpenXrSink::Impl::on_state(XrSessionState next) {
  state = next;
  switch (next) {
    case XR_SESSION_STATE_READY:
      if (!stopped && !running) {
        XrSessionBeginInfo begin{};
        begin.type = XR_TYPE_SESSION_BEGIN_INFO;
        begin.primaryViewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
        xr_frame(xrBeginSession(session, &begin), "xrBeginSession");
        running = true;
      }
      break;
    case XR_SESSION_STATE_STOPPING:
      if (running) {
        xr_frame(xrEndSession(session), "xrEndSession");
        running = false;
      }
      break;
    case XR_SESSION_STATE_EXITING:
      stop(
          "the OpenXR runtime ended the session (EXITING): the headset was taken off or the "
          "user quit");
      break;
    case XR_SESSION_STATE_LOSS_PENDING:
      running = false;  // the session is going away: no more frame calls
      stop(
          "the OpenXR runtime is losing the session (LOSS_PENDING): the headset was "
          "disconnected");
      break;
    default:
      break;
  }
}

void OpenXrSink::Impl::poll_events() {
  for (;;) {
    XrEventDataBuffer event{};
    event.type = XR_TYPE_EVENT_DATA_BUFFER;
    if (xrPollEvent(instance, &event) != XR_SUCCESS) return;
    if (event.type == XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED) {
      const auto& changed = reinterpret_cast<const XrEventDataSessionStateChanged&>(event);
      if (changed.session == session) on_state(changed.state);
    } else if (event.type == XR_TYPE_EVENT_DATA_INSTANCE_LOSS_PENDING) {
      running = false;
      stop("the OpenXR runtime is going away (instance loss pending)");
    }
  }
}

void OpenXrSink::Impl::end_frame(XrTime display_time, const StereoFrame* frame) {
  std::array<XrCompositionLayerProjectionView, 2> views{};
  XrCompositionLayerProjection layer{};
  const XrCompositionLayerBaseHeader* layers[] = {
      reinterpret_cast<const XrCompositionLayerBaseHeader*>(&layer)};
  XrFrameEndInfo end{};
  end.type = XR_TYPE_FRAME_END_INFO;
  end.displayTime = display_time;
  end.environmentBlendMode = XR_ENVIRONMENT_BLEND_MODE_OPAQUE;
  if (frame != nullptr) {
    const std::array<EyeView, 2> eye = eye_views(options.rendered, frame->pose);
    for (std::size_t e = 0; e < 2; ++e) {
      XrCompositionLayerProjectionView& v = views[e];
      v.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION_VIEW;
      v.pose = xr_pose(eye[e].position_mm, frame->pose.orientation);
      const EyeFov& fov = options.rendered.fov[e];
      v.fov = {fov.angle_left, fov.angle_right, fov.angle_up, fov.angle_down};
      v.subImage.swapchain = eyes[e].swapchain;
      v.subImage.imageRect = {
          {0, 0}, {static_cast<std::int32_t>(width), static_cast<std::int32_t>(height)}};
      v.subImage.imageArrayIndex = 0;
    }
    layer.type = XR_TYPE_COMPOSITION_LAYER_PROJECTION;
    layer.space = space;
    layer.viewCount = 2;
    layer.views = views.data();
    end.layerCount = 1;
    end.layers = layers;
  }
  xr_frame(xrEndFrame(session, &end), "xrEndFrame");
}

OpenXrSink::OpenXrSink(const std::string& application_name)
    : OpenXrSink(OpenXrSinkOptions{application_name, {}, false, false}) {}

OpenXrSink::OpenXrSink(const OpenXrSinkOptions& options) : impl_(std::make_unique<Impl>()) {
  impl_->options = options;
  impl_->create_instance();
  impl_->describe_system();
  impl_->create_vulkan();
  impl_->create_session();
  impl_->choose_format();
  impl_->poll_events();  // a runtime that is ready at once begins the session here
}

OpenXrSink::~OpenXrSink() = default;

void OpenXrSink::consume(const StereoFrame& frame) {
  Impl& s = *impl_;
  ++s.stats.frames_consumed;
  s.poll_events();
  if (!s.running || s.stopped) {
    ++s.stats.frames_dropped;
    return;
  }
  if (s.width == 0) {
    s.make_swapchains(frame.eye_width, frame.eye_height);
  } else if (frame.eye_width != s.width || frame.eye_height != s.height) {
    throw RenderError(
        "a frame of " + std::to_string(frame.eye_width) + "x" + std::to_string(frame.eye_height) +
        " per eye reached the OpenXR sink, "
        "whose swapchains are " +
        std::to_string(s.width) + "x" + std::to_string(s.height) + " (made at the first frame)");
  }
  XrFrameWaitInfo wait{};
  wait.type = XR_TYPE_FRAME_WAIT_INFO;
  XrFrameState frame_state{};
  frame_state.type = XR_TYPE_FRAME_STATE;
  const auto waiting = std::chrono::steady_clock::now();
  s.xr_frame(xrWaitFrame(s.session, &wait, &frame_state), "xrWaitFrame");
  s.stats.wait_frame_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - waiting).count();
  XrFrameBeginInfo begin{};
  begin.type = XR_TYPE_FRAME_BEGIN_INFO;
  s.xr_frame(xrBeginFrame(s.session, &begin), "xrBeginFrame");
  if (frame_state.shouldRender != XR_TRUE) {
    s.end_frame(frame_state.predictedDisplayTime, nullptr);
    ++s.stats.frames_not_rendered;
    return;
  }
  const auto uploading = std::chrono::steady_clock::now();
  s.upload(frame);
  s.stats.upload_ms +=
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - uploading)
          .count();
  s.end_frame(frame_state.predictedDisplayTime, &frame);
  ++s.stats.frames_submitted;
}

const HeadsetDescription& OpenXrSink::headset() const {
  return impl_->headset;
}
const std::string& OpenXrSink::runtime_name() const {
  return impl_->runtime;
}
OpenXrSinkStats OpenXrSink::stats() const {
  return impl_->stats;
}
std::string OpenXrSink::session_state() const {
  return state_name(impl_->state);
}
bool OpenXrSink::presenting() const {
  return impl_->running && !impl_->stopped;
}
const std::string& OpenXrSink::stop_reason() const {
  return impl_->stop_reason;
}
std::string OpenXrSink::swapchain_format() const {
  return impl_->bgra ? "VK_FORMAT_B8G8R8A8_SRGB" : "VK_FORMAT_R8G8B8A8_SRGB";
}
std::size_t OpenXrSink::validation_messages() const {
  return impl_->validation.messages.load();
}
std::vector<std::string> OpenXrSink::validation_log() const {
  const std::lock_guard<std::mutex> lock(impl_->validation.mutex);
  return impl_->validation.lines;
}

}  // namespace bisturi::render
