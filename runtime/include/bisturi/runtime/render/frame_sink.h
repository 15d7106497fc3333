#pragma once
// Where finished stereo frames go: a headset (OpenXR), files (headless), or a test.

#include <cstddef>
#include <cstdint>
#include <span>

#include "bisturi/runtime/render/headset.h"

namespace bisturi::render {

/// One finished frame: both eyes as RGBA8 (sRGB-encoded) rows, top row first, with the pose it
/// was rendered for. The pixel view lives only during FrameSink::consume.
struct StereoFrame {
  std::uint64_t index = 0;
  std::uint32_t eye_width = 0;
  std::uint32_t eye_height = 0;
  /// Left eye then right eye, each eye_width * eye_height * 4 bytes; empty when the sink did not
  /// want this frame's pixels (FrameSink::wants_pixels).
  std::span<const std::uint8_t> pixels;
  HeadPose pose;                        ///< pose.sample_time: when the tracker sampled it
  PoseClock::time_point submit_time{};  ///< when the frame's commands were submitted
  PoseClock::time_point ready_time{};   ///< when the image was finished and handed to the sink

  [[nodiscard]] std::span<const std::uint8_t> eye(int e) const {
    const std::size_t bytes = std::size_t{eye_width} * eye_height * 4;
    return pixels.subspan(static_cast<std::size_t>(e) * bytes, bytes);
  }
};

class FrameSink {
 public:
  virtual ~FrameSink() = default;
  /// Takes a finished frame (called on the render thread, in frame order).
  virtual void consume(const StereoFrame& frame) = 0;
  /// Whether frame `index` needs its pixels read back from the device. A sink that keeps only
  /// some frames says no to the others: they still come to consume(), with no pixels, for their
  /// timing, and the device skips copying them out (8 MB a frame at 2 x 1024 x 1024).
  [[nodiscard]] virtual bool wants_pixels(std::uint64_t /*index*/) const { return true; }
};

}  // namespace bisturi::render
