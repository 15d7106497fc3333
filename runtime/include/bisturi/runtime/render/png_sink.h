#pragma once
// The headless frame sink: PNG files (per eye or both eyes side by side) and, per frame, the head
// pose, the time it was sampled and the motion-to-photon latency, as lines of frames.csv.

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <memory>
#include <vector>

#include "bisturi/runtime/render/frame_sink.h"

namespace bisturi::render {

enum class PngLayout : std::uint8_t { SideBySide, PerEye };

struct PngSinkOptions {
  PngLayout layout = PngLayout::SideBySide;
  /// Write every n-th frame's image (the pose line is written for every frame).
  std::uint32_t every = 1;
};

class PngWriter;

/// Images are encoded and written on a worker thread (the render thread only copies the pixels);
/// call finish() before reading the files.
class PngSink : public FrameSink {
 public:
  /// Creates `directory` if needed; throws RenderError when it cannot be written.
  explicit PngSink(std::filesystem::path directory, const PngSinkOptions& options = {});
  ~PngSink() override;
  void consume(const StereoFrame& frame) override;
  /// Only the frames written as images (every n-th).
  [[nodiscard]] bool wants_pixels(std::uint64_t index) const override {
    return index % options_.every == 0;
  }
  /// Waits until every image is written and frames.csv flushed; throws RenderError on a failure.
  void finish();

  /// Motion-to-photon latency of every consumed frame (ready time minus pose sample time).
  [[nodiscard]] const std::vector<double>& latencies_ms() const { return latencies_ms_; }
  /// Images written so far (all of them after finish()).
  [[nodiscard]] std::size_t images_written() const;

 private:
  std::filesystem::path directory_;
  PngSinkOptions options_;
  std::ofstream poses_;
  std::vector<double> latencies_ms_;
  std::unique_ptr<PngWriter> writer_;
};

/// Writes RGBA8 rows (top first) as a PNG; throws RenderError on failure.
void write_png(const std::filesystem::path& file, std::uint32_t width, std::uint32_t height,
               const std::uint8_t* rgba, std::size_t row_stride_bytes);

}  // namespace bisturi::render
