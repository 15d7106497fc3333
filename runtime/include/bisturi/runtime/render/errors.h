#pragma once
// Errors of the renderer and the frame sinks. Callers catch the specific ones to fall back: no
// Vulkan device (tests skip, the session reports it), no OpenXR runtime (the session writes frames
// through the headless sink instead).

#include <stdexcept>
#include <string>

namespace bisturi::render {

class RenderError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// No Vulkan loader, no driver, or no device with what the renderer needs (Vulkan 1.2, multiview).
class NoVulkanDevice : public RenderError {
 public:
  using RenderError::RenderError;
};

/// No OpenXR runtime is installed or active, or it has no headset to show frames on.
class XrUnavailable : public RenderError {
 public:
  using RenderError::RenderError;
};

}  // namespace bisturi::render
