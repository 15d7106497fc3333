#pragma once
// The headset sink through OpenXR. Construction asks the loader for a runtime and a head-mounted
// system; when there is none (no runtime installed, XR_RUNTIME_JSON unset, no headset) it throws
// XrUnavailable with the reason, which the session catches to fall back to the headless sink.

#include <memory>
#include <string>

#include "bisturi/runtime/render/frame_sink.h"
#include "bisturi/runtime/render/headset.h"

namespace bisturi::render {

class OpenXrSink : public FrameSink {
 public:
  /// Throws XrUnavailable when no OpenXR runtime or headset can be used.
  explicit OpenXrSink(const std::string& application_name = "bisturi");
  ~OpenXrSink() override;
  void consume(const StereoFrame& frame) override;

  /// The headset as the runtime describes it (recommended resolution per eye).
  [[nodiscard]] const HeadsetDescription& headset() const;
  [[nodiscard]] const std::string& runtime_name() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bisturi::render
