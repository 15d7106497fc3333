#pragma once
// A one-line progress display for long work: "stage:  42%" rewritten in place on stderr when
// stderr is a terminal, silent otherwise (scripts and CI logs stay clean).

#include <unistd.h>

#include <cstddef>
#include <cstdio>
#include <string>
#include <string_view>

namespace bisturi::cli {

class ProgressLine {
 public:
  ProgressLine() : enabled_(isatty(STDERR_FILENO) != 0) {}
  explicit ProgressLine(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO) != 0) {}
  ~ProgressLine() { clear(); }
  ProgressLine(const ProgressLine&) = delete;
  ProgressLine& operator=(const ProgressLine&) = delete;

  void show(std::string_view stage, std::size_t done, std::size_t total) {
    if (!enabled_ || total == 0) return;
    const int percent = static_cast<int>(done * 100 / total);
    if (stage == stage_ && percent == percent_) return;
    stage_ = stage;
    percent_ = percent;
    std::fprintf(stderr, "\r%s: %3d%%\033[K", stage_.c_str(), percent);
    std::fflush(stderr);
    shown_ = true;
  }
  /// A finished stage: its line stays on the terminal with the time it took.
  void done(std::string_view stage, double milliseconds) {
    if (!enabled_) return;
    std::fprintf(stderr, "\r%.*s: done in %.1f ms\033[K\n", static_cast<int>(stage.size()),
                 stage.data(), milliseconds);
    std::fflush(stderr);
    shown_ = false;
    stage_.clear();
    percent_ = -1;
  }
  void clear() {
    if (shown_) std::fprintf(stderr, "\r\033[K");
    shown_ = false;
  }

 private:
  bool enabled_;
  bool shown_ = false;
  std::string stage_;
  int percent_ = -1;
};

}  // namespace bisturi::cli
