#include "bisturi/runtime/render/openxr_sink.h"

#include <openxr/openxr.h>

#include <cstring>
#include <vector>

#include "bisturi/runtime/render/errors.h"

namespace bisturi::render {

namespace {

constexpr const char* kVulkanExtension = "XR_KHR_vulkan_enable2";

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

}  // namespace

struct OpenXrSink::Impl {
  XrInstance instance = XR_NULL_HANDLE;
  XrSystemId system = XR_NULL_SYSTEM_ID;
  HeadsetDescription headset;
  std::string runtime;

  ~Impl() {
    if (instance != XR_NULL_HANDLE) xrDestroyInstance(instance);
  }
};

OpenXrSink::OpenXrSink(const std::string& application_name) : impl_(std::make_unique<Impl>()) {
  const std::string fallback = "; frames can go to the headless (PNG) sink instead";
  // The renderer hands frames over through Vulkan: the runtime must offer XR_KHR_vulkan_enable2.
  std::uint32_t count = 0;
  XrResult r = xrEnumerateInstanceExtensionProperties(nullptr, 0, &count, nullptr);
  if (XR_FAILED(r)) {
    throw XrUnavailable("no OpenXR runtime is available (" + xr_result(XR_NULL_HANDLE, r) +
                        "): none is installed, or XR_RUNTIME_JSON does not name one" + fallback);
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
    throw XrUnavailable("the OpenXR runtime does not offer " +
                        std::string("XR_KHR_vulkan_enable2") + fallback);
  }
  XrInstanceCreateInfo info{};
  info.type = XR_TYPE_INSTANCE_CREATE_INFO;
  std::strncpy(info.applicationInfo.applicationName, application_name.c_str(),
               XR_MAX_APPLICATION_NAME_SIZE - 1);
  std::strncpy(info.applicationInfo.engineName, "bisturi", XR_MAX_ENGINE_NAME_SIZE - 1);
  info.applicationInfo.apiVersion = XR_CURRENT_API_VERSION;
  const char* enabled[] = {kVulkanExtension};
  info.enabledExtensionCount = 1;
  info.enabledExtensionNames = enabled;
  r = xrCreateInstance(&info, &impl_->instance);
  if (XR_FAILED(r)) {
    throw XrUnavailable("no OpenXR runtime is available (xrCreateInstance: " +
                        xr_result(XR_NULL_HANDLE, r) + ")" + fallback);
  }
  XrInstanceProperties props{};
  props.type = XR_TYPE_INSTANCE_PROPERTIES;
  if (XR_SUCCEEDED(xrGetInstanceProperties(impl_->instance, &props))) {
    impl_->runtime = props.runtimeName;
  }
  XrSystemGetInfo system{};
  system.type = XR_TYPE_SYSTEM_GET_INFO;
  system.formFactor = XR_FORM_FACTOR_HEAD_MOUNTED_DISPLAY;
  r = xrGetSystem(impl_->instance, &system, &impl_->system);
  if (XR_FAILED(r)) {
    throw XrUnavailable("the OpenXR runtime " + impl_->runtime + " has no headset (" +
                        xr_result(impl_->instance, r) + ")" + fallback);
  }
  std::uint32_t views = 0;
  r = xrEnumerateViewConfigurationViews(impl_->instance, impl_->system,
                                        XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, 0, &views,
                                        nullptr);
  XrViewConfigurationView blank{};
  blank.type = XR_TYPE_VIEW_CONFIGURATION_VIEW;
  std::vector<XrViewConfigurationView> config(views, blank);
  if (XR_SUCCEEDED(r) && views == 2) {
    xrEnumerateViewConfigurationViews(impl_->instance, impl_->system,
                                      XR_VIEW_CONFIGURATION_TYPE_PRIMARY_STEREO, views, &views,
                                      config.data());
    impl_->headset.eye_width = config[0].recommendedImageRectWidth;
    impl_->headset.eye_height = config[0].recommendedImageRectHeight;
  }
  // Sessions, swapchains and frame submission (xrBeginFrame / xrEndFrame with the renderer's
  // images) are not written yet: no runtime could be tested here.
  throw XrUnavailable("the OpenXR runtime " + impl_->runtime +
                      " was found, but presenting frames through OpenXR is not implemented in "
                      "this build" +
                      fallback);
}

OpenXrSink::~OpenXrSink() = default;

void OpenXrSink::consume(const StereoFrame& /*frame*/) {
  throw XrUnavailable("presenting frames through OpenXR is not implemented in this build");
}

const HeadsetDescription& OpenXrSink::headset() const {
  return impl_->headset;
}
const std::string& OpenXrSink::runtime_name() const {
  return impl_->runtime;
}

}  // namespace bisturi::render
