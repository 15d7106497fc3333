#pragma once
// The headless frame sink: PNG files (per eye or both eyes side by side) and, per frame, the head
// pose, the time it was sampled and the motion-to-photon latency, as lines of frames.csv.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <vector>

#include "bisturi/runtime/render/frame_sink.h"

namespace bisturi::render {

enum class PngLayout : std::uint8_t { SideBySide, PerEye };

struct PngSinkOptions {
  PngLayout layout = PngLayout::SideBySide;
  /// Write every n-th frame's image (the pose line is written for every frame).
  std::uint32_t every = 1;
};

class PngSink : public FrameSink {
 public:
  /// Creates `directory` if needed; throws RenderError when it cannot be written.
  explicit PngSink(std::filesystem::path directory, const PngSinkOptions& options = {});
  void consume(const StereoFrame& frame) override;

  /// Motion-to-photon latency of every consumed frame (ready time minus pose sample time).
  [[nodiscard]] const std::vector<double>& latencies_ms() const { return latencies_ms_; }
  [[nodiscard]] std::size_t images_written() const { return images_; }

 private:
  std::filesystem::path directory_;
  PngSinkOptions options_;
  std::ofstream poses_;
  std::vector<double> latencies_ms_;
  std::size_t images_ = 0;
};

/// Writes RGBA8 rows (top first) as a PNG; throws RenderError on failure.
void write_png(const std::filesystem::path& file, std::uint32_t width, std::uint32_t height,
               const std::uint8_t* rgba, std::size_t row_stride_bytes);

}  // namespace bisturi::render
