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

}  // namespace

const char* xr_detail::state_name(XrSessionState state) {
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
  bool vulkan = false, timespec = false;
  for (const XrExtensionProperties& e : extensions) {
    vulkan = vulkan || std::strcmp(e.extensionName, kVulkanExtension) == 0;
    timespec = timespec || std::strcmp(e.extensionName, kTimespecExtension) == 0;
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
  // XR_KHR_convert_timespec_time, where offered, puts the runtime's times on the steady clock
  // (motion-to-photon runs to the predicted display time).
  const char* enabled[] = {kVulkanExtension, kTimespecExtension};
  info.enabledExtensionCount = timespec ? 2 : 1;
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
  if (timespec) load("xrConvertTimeToTimespecTimeKHR", time_to_timespec);
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
  binding.instance = context->instance();
  binding.physicalDevice = context->physical_device();
  binding.device = context->device();
  binding.queueFamilyIndex = context->queue_family();
  binding.queueIndex = 0;
  XrSessionCreateInfo info{};
  info.type = XR_TYPE_SESSION_CREATE_INFO;
  info.next = &binding;
  info.systemId = system;
  xr_setup(xrCreateSession(instance, &info, &session), "xrCreateSession");

  space_type = XR_REFERENCE_SPACE_TYPE_LOCAL;
  if (options.stage_space) {
    std::uint32_t count = 0;
    xr_setup(xrEnumerateReferenceSpaces(session, 0, &count, nullptr), "xrEnumerateReferenceSpaces");
    std::vector<XrReferenceSpaceType> spaces(count);
    xr_setup(xrEnumerateReferenceSpaces(session, count, &count, spaces.data()),
             "xrEnumerateReferenceSpaces");
    if (std::find(spaces.begin(), spaces.end(), XR_REFERENCE_SPACE_TYPE_STAGE) != spaces.end()) {
      space_type = XR_REFERENCE_SPACE_TYPE_STAGE;
    }
  }
  XrReferenceSpaceCreateInfo space_info{};
  space_info.type = XR_TYPE_REFERENCE_SPACE_CREATE_INFO;
  space_info.referenceSpaceType = space_type;
  space_info.poseInReferenceSpace.orientation.w = 1.0f;
  xr_setup(xrCreateReferenceSpace(session, &space_info, &space), "xrCreateReferenceSpace");
  space_info.referenceSpaceType = XR_REFERENCE_SPACE_TYPE_VIEW;
  xr_setup(xrCreateReferenceSpace(session, &space_info, &view_space), "xrCreateReferenceSpace");
  if (options.controller) attach_input();
}

void OpenXrSink::Impl::choose_format() {
  std::uint32_t count = 0;
  xr_setup(xrEnumerateSwapchainFormats(session, 0, &count, nullptr), "xrEnumerateSwapchainFormats");
  std::vector<std::int64_t> formats(count);
  xr_setup(xrEnumerateSwapchainFormats(session, count, &count, formats.data()),
           "xrEnumerateSwapchainFormats");
  // The renderer writes sRGB-encoded bytes (shaders/mesh.frag) through a UNORM view of an sRGB
  // image (a mutable-format swapchain): the compositor reads the colours the PNG sink writes.
  for (const auto& [wanted, view] :
       {std::pair{VK_FORMAT_R8G8B8A8_SRGB, VK_FORMAT_R8G8B8A8_UNORM},
        std::pair{VK_FORMAT_B8G8R8A8_SRGB, VK_FORMAT_B8G8R8A8_UNORM}}) {
    if (std::find(formats.begin(), formats.end(), wanted) != formats.end()) {
      format = wanted;
      view_format = view;
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

XrTime OpenXrSink::Impl::now_xr() const {
  // Without XR_KHR_convert_timespec_time, XrTime is taken as CLOCK_MONOTONIC nanoseconds, which
  // it is in Monado (and the simulated runtime); PoseClock is that clock on Linux.
  return std::chrono::duration_cast<std::chrono::nanoseconds>(PoseClock::now().time_since_epoch())
      .count();
}

PoseClock::time_point OpenXrSink::Impl::to_pose_clock(XrTime time) const {
  std::int64_t ns = time;
  timespec t{};
  if (time_to_timespec != nullptr && XR_SUCCEEDED(time_to_timespec(instance, time, &t))) {
    ns = static_cast<std::int64_t>(t.tv_sec) * 1'000'000'000 + t.tv_nsec;
  }
  return PoseClock::time_point(
      std::chrono::duration_cast<PoseClock::duration>(std::chrono::nanoseconds(ns)));
}

void OpenXrSink::Impl::stop(std::string reason) {
  if (!stopped) stop_reason = std::move(reason);
  stopped = true;
}

bool OpenXrSink::Impl::xr_frame(XrResult r, const char* what) {
  if (XR_SUCCEEDED(r)) return true;
  if (r == XR_ERROR_SESSION_LOST) {
    lose_session();
    return false;
  }
  if (r == XR_ERROR_INSTANCE_LOST) {
    running = false;
    stop(std::string("the OpenXR runtime went away (") + what + ": XR_ERROR_INSTANCE_LOST)");
    return false;
  }
  throw RenderError(std::string("OpenXR ") + what + " failed: " + xr_result(instance, r));
}

void OpenXrSink::Impl::on_state(XrSessionState next, XrTime time) {
  state = next;
  changes.push_back({xr_detail::state_name(next), to_pose_clock(time)});
  switch (next) {
    case XR_SESSION_STATE_READY:
      if (!stopped && !running) {
        XrSessionBeginInfo begin{};
        begin.type = XR_TYPE_SESSION_BEGIN_INFO;
        begin.primaryViewConfigurationType = XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO;
        if (xr_frame(xrBeginSession(session, &begin), "xrBeginSession")) running = true;
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
      lose_session();
      break;
    default:
      break;
  }
}

void OpenXrSink::Impl::poll_events() {
  while (instance != XR_NULL_HANDLE) {
    XrEventDataBuffer event{};
    event.type = XR_TYPE_EVENT_DATA_BUFFER;
    const XrResult r = xrPollEvent(instance, &event);
    if (r == XR_ERROR_INSTANCE_LOST) {
      xr_frame(r, "xrPollEvent");
      return;
    }
    if (r != XR_SUCCESS) return;
    if (event.type == XR_TYPE_EVENT_DATA_SESSION_STATE_CHANGED) {
      const auto& changed = reinterpret_cast<const XrEventDataSessionStateChanged&>(event);
      if (changed.session == session && session != XR_NULL_HANDLE) {
        on_state(changed.state, changed.time);
      }
    } else if (event.type == XR_TYPE_EVENT_DATA_INSTANCE_LOSS_PENDING) {
      running = false;
      stop("the OpenXR runtime is going away (instance loss pending)");
    }
  }
}

void OpenXrSink::Impl::destroy_session() {
  destroy_swapchain();
  if (grip_space != XR_NULL_HANDLE) xrDestroySpace(grip_space);
  grip_space = XR_NULL_HANDLE;
  if (view_space != XR_NULL_HANDLE) xrDestroySpace(view_space);
  if (space != XR_NULL_HANDLE) xrDestroySpace(space);
  if (session != XR_NULL_HANDLE) xrDestroySession(session);
  view_space = space = XR_NULL_HANDLE;
  session = XR_NULL_HANDLE;
  running = false;
}

void OpenXrSink::Impl::lose_session() {
  if (lost || session == XR_NULL_HANDLE) return;
  // The session is going away: nothing more is shown. Its objects go now; a new session is
  // made once the runtime has the headset again (try_recreate).
  ++stats.sessions_lost;
  lost = true;
  running = false;
  have_views = false;  // the new session's views are located afresh
  destroy_session();
  next_system_try = PoseClock::now();
}

void OpenXrSink::Impl::try_recreate() {
  if (!lost || stopped || PoseClock::now() < next_system_try) return;
  next_system_try = PoseClock::now() + std::chrono::milliseconds(50);
  XrSystemGetInfo info{};
  info.type = XR_TYPE_SYSTEM_GET_INFO;
  info.formFactor = XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY;
  XrSystemId again = XR_NULL_SYSTEM_ID;
  const XrResult r = xrGetSystem(instance, &info, &again);
  if (r == XR_ERROR_FORM_FACTOR_UNAVAILABLE) return;  // not back yet
  if (!xr_frame(r, "xrGetSystem")) return;
  // The renderer's device must be the one the runtime shows from: the same system and device.
  XrGraphicsRequirementsVulkan2KHR requirements{};
  requirements.type = XR_TYPE_GRAPHICS_REQUIREMENTS_VULKAN2_KHR;
  if (!xr_frame(get_requirements(instance, again, &requirements),
                "xrGetVulkanGraphicsRequirements2KHR")) {
    return;
  }
  XrVulkanGraphicsDeviceGetInfoKHR device_info{};
  device_info.type = XR_TYPE_VULKAN_GRAPHICS_DEVICE_GET_INFO_KHR;
  device_info.systemId = again;
  device_info.vulkanInstance = context->instance();
  VkPhysicalDevice physical = VK_NULL_HANDLE;
  if (!xr_frame(get_vk_device(instance, &device_info, &physical),
                "xrGetVulkanGraphicsDevice2KHR")) {
    return;
  }
  if (physical != context->physical_device()) {
    stop(
        "the OpenXR runtime came back on another Vulkan device than the one the renderer draws on");
    return;
  }
  system = again;
  try {
    create_session();
    make_swapchain(width, height);
  } catch (const XrUnavailable& e) {
    stop(std::string("the OpenXR session could not be made again: ") + e.what());
    return;
  }
  lost = false;
  ++stats.sessions_recreated;
  poll_events();  // READY begins it
}

OpenXrSink::OpenXrSink(const std::string& application_name)
    : OpenXrSink(OpenXrSinkOptions{.application_name = application_name}) {}

OpenXrSink::OpenXrSink(const OpenXrSinkOptions& options) : impl_(std::make_unique<Impl>()) {
  Impl& s = *impl_;
  s.options = options;
  if (const char* log = std::getenv("BISTURI_XR_VIEWS_LOG"); log != nullptr && *log != '\0') {
    s.views_log = std::fopen(log, "w");
  }
  s.create_instance();
  s.describe_system();
  if (options.controller) s.create_input();
  s.create_vulkan();
  s.create_session();
  s.choose_format();
  s.make_swapchain(options.eye_width != 0 ? options.eye_width : s.headset.eye_width,
                   options.eye_height != 0 ? options.eye_height : s.headset.eye_height);
  s.poll_events();  // a runtime that is ready at once begins the session here
}

OpenXrSink::~OpenXrSink() = default;

HeadsetFrame OpenXrSink::begin_frame() {
  return impl_->begin_frame();
}
void OpenXrSink::end_frame(const HeadsetFrame& frame, bool rendered) {
  impl_->end_frame(frame, rendered);
}
void OpenXrSink::consume(const StereoFrame& /*frame*/) {}
void OpenXrSink::stall_next_image_wait(std::chrono::nanoseconds duration) {
  impl_->stall_next_image_wait = duration;
}

bool OpenXrSink::vibrate(float amplitude, double duration_s) {
  return impl_->vibrate(amplitude, duration_s);
}
void OpenXrSink::finish() {
  impl_->finish();
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
  return xr_detail::state_name(impl_->state);
}
const std::vector<XrStateChange>& OpenXrSink::state_changes() const {
  return impl_->changes;
}
std::string OpenXrSink::reference_space() const {
  return impl_->space_type == XR_REFERENCE_SPACE_TYPE_STAGE ? "STAGE" : "LOCAL";
}
bool OpenXrSink::presenting() const {
  return impl_->running && !impl_->stopped &&
         (impl_->state == XR_SESSION_STATE_VISIBLE || impl_->state == XR_SESSION_STATE_FOCUSED);
}
bool OpenXrSink::stopped() const {
  return impl_->stopped;
}
const std::string& OpenXrSink::stop_reason() const {
  return impl_->stop_reason;
}
std::string OpenXrSink::swapchain_format() const {
  return impl_->format == VK_FORMAT_B8G8R8A8_SRGB ? "VK_FORMAT_B8G8R8A8_SRGB"
                                                  : "VK_FORMAT_R8G8B8A8_SRGB";
}
std::size_t OpenXrSink::validation_messages() const {
  return impl_->context ? impl_->context->validation_messages() : 0;
}
std::vector<std::string> OpenXrSink::validation_log() const {
  return impl_->context ? impl_->context->validation_log() : std::vector<std::string>{};
}

}  // namespace bisturi::render
