#pragma once
// Timing samples of a session (haptic period, step time, frame time, latencies) and their
// summaries. A recorder preallocates its storage, so recording on the hot path never allocates;
// when full it keeps every n-th sample (a uniform thinning) so long sessions stay bounded. The
// thinning moves a few samples per record, so no one record (a haptic tick's) pays for a whole
// buffer.

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
  /// The kept samples, in the order they came (a thinning under way is finished first).
  [[nodiscard]] const std::vector<double>& samples() const;
  [[nodiscard]] const std::string& unit() const { return unit_; }
  [[nodiscard]] std::size_t count() const { return count_; }

 private:
  /// Samples a thinning moves per record: a full buffer of 2^20 takes 8192 records.
  static constexpr std::size_t kMovesPerRecord = 64;
  /// Moves up to `moves` samples of the thinning under way; at its end, the samples that came
  /// meanwhile follow the kept ones. Const: the readers finish a thinning before they read.
  void thin(std::size_t moves) const;

  std::string unit_;
  mutable std::vector<double> samples_;
  /// The samples that come while a thinning is under way (reserved for all of them).
  mutable std::vector<double> arriving_;
  mutable std::size_t thinned_ = 0;  ///< samples_[2k] moved to k for every k below this
  mutable bool thinning_ = false;
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
