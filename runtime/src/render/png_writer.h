#pragma once
// PNG encoding off the render thread: images are queued (at most `depth` at a time; a full queue
// makes the caller wait, so no requested image is lost) and one worker thread encodes and writes
// them in order. A 2 x 1024^2 frame takes tens of milliseconds to encode; done inline it stalled
// every image frame of a session and with it the frames (and the latency) of the next events.

#include <condition_variable>
#include <cstdint>
#include <deque>
#include <exception>
#include <filesystem>
#include <mutex>
#include <thread>
#include <vector>

namespace bisturi::render {

class PngWriter {
 public:
  explicit PngWriter(std::size_t depth = 3);
  ~PngWriter();  // waits for the queued images; errors are dropped (call finish() to see them)
  PngWriter(const PngWriter&) = delete;
  PngWriter& operator=(const PngWriter&) = delete;

  /// Queues tightly packed RGBA8 rows; throws RenderError for an earlier image that failed.
  void write(std::filesystem::path file, std::uint32_t width, std::uint32_t height,
             std::vector<std::uint8_t> rgba);
  /// Waits until every queued image is written; throws RenderError for the first that failed.
  void finish();
  [[nodiscard]] std::size_t written() const;

 private:
  struct Job {
    std::filesystem::path file;
    std::uint32_t width = 0, height = 0;
    std::vector<std::uint8_t> rgba;
  };
  void run();
  void rethrow_failure();

  std::size_t depth_;
  mutable std::mutex mutex_;
  std::condition_variable changed_;
  std::deque<Job> jobs_;
  bool busy_ = false;
  bool stopping_ = false;
  std::size_t written_ = 0;
  std::exception_ptr failure_;
  std::thread worker_;
};

}  // namespace bisturi::render
