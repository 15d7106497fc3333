#pragma once
// Timing samples of a session (haptic period, step time, frame time, latencies) and their
// summaries. A recorder preallocates its storage, so recording on the hot path never allocates;
// when full it keeps every n-th sample (a uniform thinning) so long sessions stay bounded.

#include <cstddef>
#include <string>
#include <vector>

namespace bisturi::runtime {

struct TimingSummary {
  std::size_t count = 0;  ///< samples recorded (before any thinning)
  double mean = 0.0;
  double p50 = 0.0;
  double p95 = 0.0;
  double p99 = 0.0;
  double max = 0.0;
  double min = 0.0;
};

class TimingRecorder {
 public:
  /// `unit` names what the samples are measured in ("ms", "us"), for reports.
  explicit TimingRecorder(std::string unit = "ms", std::size_t capacity = 1 << 20);

  /// Not thread-safe: one recorder per thread (or per producer).
  void record(double value);

  [[nodiscard]] TimingSummary summary() const;
  [[nodiscard]] const std::vector<double>& samples() const { return samples_; }
  [[nodiscard]] const std::string& unit() const { return unit_; }
  [[nodiscard]] std::size_t count() const { return count_; }

 private:
  std::string unit_;
  std::vector<double> samples_;
  std::size_t capacity_;
  std::size_t count_ = 0;
  std::size_t stride_ = 1;  // keep one sample in `stride_` once the buffer has filled
  double max_ = 0.0;
  double min_ = 0.0;
  double sum_ = 0.0;
};

/// Percentile (0..100) of a sample set by linear interpolation between order statistics; 0 for
/// an empty set.
double percentile(std::vector<double> values, double p);

}  // namespace bisturi::runtime
