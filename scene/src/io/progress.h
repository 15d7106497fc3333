#pragma once
// Calls ReadOptions::progress about every MiB of input: cheap enough to ask per element.

#include <cstddef>
#include <limits>

#include "bisturi/scene/io/mesh_file.h"

namespace bisturi::mesh_io {

class ProgressTicker {
 public:
  ProgressTicker(const ReadOptions& options, std::size_t total)
      : callback_(options.progress ? &options.progress : nullptr),
        total_(total),
        next_(callback_ != nullptr ? kStep : std::numeric_limits<std::size_t>::max()) {}

  void at(std::size_t done) {
    if (done >= next_) [[unlikely]] {
      report(done);
    }
  }
  void finish() const {
    if (callback_ != nullptr) (*callback_)(total_, total_);
  }

 private:
  void report(std::size_t done) {
    next_ = done + kStep;
    if (callback_ != nullptr) (*callback_)(done, total_);
  }

  static constexpr std::size_t kStep = std::size_t{1} << 20;
  const std::function<void(std::size_t, std::size_t)>* callback_;
  std::size_t total_;
  std::size_t next_;
};

}  // namespace bisturi::mesh_io
