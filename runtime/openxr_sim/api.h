#pragma once
// The entry points the simulated runtime implements, declared with the types of openxr.h's
// function pointers (so a signature mismatch does not compile).

#include <type_traits>

#include "sim.h"

// clang-format off
// Core functions implemented here.
#define BISTURI_XRSIM_CORE(_) \
  _(EnumerateInstanceExtensionProperties) \
  _(CreateInstance) \
  _(DestroyInstance) \
  _(GetInstanceProperties) \
  _(ResultToString) \
  _(StructureTypeToString) \
  _(GetSystem) \
  _(GetSystemProperties) \
  _(EnumerateViewConfigurations) \
  _(EnumerateViewConfigurationViews) \
  _(EnumerateEnvironmentBlendModes) \
  _(PollEvent) \
  _(CreateSession) \
  _(DestroySession) \
  _(BeginSession) \
  _(EndSession) \
  _(RequestExitSession) \
  _(EnumerateReferenceSpaces) \
  _(CreateReferenceSpace) \
  _(DestroySpace) \
  _(EnumerateSwapchainFormats) \
  _(CreateSwapchain) \
  _(DestroySwapchain) \
  _(EnumerateSwapchainImages) \
  _(AcquireSwapchainImage) \
  _(WaitSwapchainImage) \
  _(ReleaseSwapchainImage) \
  _(WaitFrame) \
  _(BeginFrame) \
  _(EndFrame) \
  _(LocateViews) \
  _(LocateSpace) \
  _(StringToPath) \
  _(PathToString) \
  _(CreateActionSet) \
  _(DestroyActionSet) \
  _(CreateAction) \
  _(DestroyAction) \
  _(SuggestInteractionProfileBindings) \
  _(AttachSessionActionSets) \
  _(CreateActionSpace) \
  _(SyncActions) \
  _(GetActionStateFloat) \
  _(GetActionStatePose) \
  _(ApplyHapticFeedback) \
  _(StopHapticFeedback)

// XR_KHR_vulkan_enable2, the one extension offered.
#define BISTURI_XRSIM_VULKAN(_) \
  _(GetVulkanGraphicsRequirements2KHR) \
  _(CreateVulkanInstanceKHR) \
  _(GetVulkanGraphicsDevice2KHR) \
  _(CreateVulkanDeviceKHR)

// XR_KHR_convert_timespec_time (XrTime is CLOCK_MONOTONIC nanoseconds here).
#define BISTURI_XRSIM_TIMESPEC(_) \
  _(ConvertTimespecTimeToTimeKHR) \
  _(ConvertTimeToTimespecTimeKHR)

// Core functions not implemented: the loader fills its dispatch table with every core function,
// so these answer XR_ERROR_FUNCTION_UNSUPPORTED when called instead of being null.
#define BISTURI_XRSIM_UNSUPPORTED(_) \
  _(EnumerateApiLayerProperties) \
  _(EnumerateBoundSourcesForAction) \
  _(GetActionStateBoolean) \
  _(GetActionStateVector2f) \
  _(GetCurrentInteractionProfile) \
  _(GetInputSourceLocalizedName) \
  _(GetReferenceSpaceBoundsRect) \
  _(GetViewConfigurationProperties)
// clang-format on

namespace bisturi::xrsim {

#define BISTURI_XRSIM_DECLARE(name) extern std::remove_pointer_t<PFN_xr##name> name;
BISTURI_XRSIM_CORE(BISTURI_XRSIM_DECLARE)
BISTURI_XRSIM_VULKAN(BISTURI_XRSIM_DECLARE)
BISTURI_XRSIM_TIMESPEC(BISTURI_XRSIM_DECLARE)
#undef BISTURI_XRSIM_DECLARE

}  // namespace bisturi::xrsim
