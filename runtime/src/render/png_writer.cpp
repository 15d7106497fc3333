// PNG encoding off the render thread (see png_writer.h).

#include "png_writer.h"

#include "bisturi/runtime/render/errors.h"
#include "bisturi/runtime/render/png_sink.h"

namespace bisturi::render {

PngWriter::PngWriter(std::size_t depth) : depth_(depth == 0 ? 1 : depth) {
  worker_ = std::thread([this] { run(); });
}

PngWriter::~PngWriter() {
  {
    std::lock_guard lock(mutex_);
    stopping_ = true;
  }
  changed_.notify_all();
  worker_.join();
}

void PngWriter::rethrow_failure() {
  if (!failure_) return;
  const std::exception_ptr f = failure_;
  failure_ = nullptr;
  std::rethrow_exception(f);
}

void PngWriter::write(std::filesystem::path file, std::uint32_t width, std::uint32_t height,
                      std::vector<std::uint8_t> rgba) {
  std::unique_lock lock(mutex_);
  rethrow_failure();
  changed_.wait(lock, [&] { return jobs_.size() < depth_; });
  jobs_.push_back({std::move(file), width, height, std::move(rgba)});
  lock.unlock();
  changed_.notify_all();
}

void PngWriter::finish() {
  std::unique_lock lock(mutex_);
  changed_.wait(lock, [&] { return jobs_.empty() && !busy_; });
  rethrow_failure();
}

std::size_t PngWriter::written() const {
  std::lock_guard lock(mutex_);
  return written_;
}

void PngWriter::run() {
  std::unique_lock lock(mutex_);
  for (;;) {
    changed_.wait(lock, [&] { return stopping_ || !jobs_.empty(); });
    if (jobs_.empty()) return;  // stopping, and nothing left to write
    Job job = std::move(jobs_.front());
    jobs_.pop_front();
    busy_ = true;
    lock.unlock();
    changed_.notify_all();  // a slot is free
    std::exception_ptr failed;
    try {
      write_png(job.file, job.width, job.height, job.rgba.data(), std::size_t{job.width} * 4);
    } catch (...) {
      failed = std::current_exception();
    }
    lock.lock();
    busy_ = false;
    if (failed && !failure_) failure_ = failed;
    if (!failed) ++written_;
    changed_.notify_all();
  }
}

}  // namespace bisturi::render
