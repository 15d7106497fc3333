#include "bisturi/runtime/session/timing.h"

#include <algorithm>
#include <cmath>

namespace bisturi::runtime {

namespace {

double percentile_of_sorted(const std::vector<double>& sorted, double p) {
  if (sorted.empty()) return 0.0;
  const double pos = std::clamp(p, 0.0, 100.0) / 100.0 * static_cast<double>(sorted.size() - 1);
  const auto lo = static_cast<std::size_t>(std::floor(pos));
  const std::size_t hi = std::min(lo + 1, sorted.size() - 1);
  return sorted[lo] + (sorted[hi] - sorted[lo]) * (pos - static_cast<double>(lo));
}

}  // namespace

TimingRecorder::TimingRecorder(std::string unit, std::size_t capacity)
    : unit_(std::move(unit)), capacity_(std::max<std::size_t>(capacity, 2)) {
  samples_.reserve(capacity_);
}

void TimingRecorder::record(double value) {
  if (count_ == 0) {
    max_ = min_ = value;
  } else {
    max_ = std::max(max_, value);
    min_ = std::min(min_, value);
  }
  sum_ += value;
  if (count_ % stride_ == 0) {
    if (samples_.size() == capacity_) {
      // Full: keep every other sample and halve the rate from now on.
      std::size_t kept = 0;
      for (std::size_t i = 0; i < samples_.size(); i += 2)
        samples_[kept++] = samples_[i];
      samples_.resize(kept);
      stride_ *= 2;
    }
    if (count_ % stride_ == 0) samples_.push_back(value);
  }
  ++count_;
}

TimingSummary TimingRecorder::summary() const {
  TimingSummary s;
  s.count = count_;
  if (count_ == 0) return s;
  s.mean = sum_ / static_cast<double>(count_);
  s.max = max_;
  s.min = min_;
  std::vector<double> sorted = samples_;
  std::sort(sorted.begin(), sorted.end());
  s.p50 = percentile_of_sorted(sorted, 50.0);
  s.p95 = percentile_of_sorted(sorted, 95.0);
  s.p99 = percentile_of_sorted(sorted, 99.0);
  return s;
}

double percentile(std::vector<double> values, double p) {
  std::sort(values.begin(), values.end());
  return percentile_of_sorted(values, p);
}

}  // namespace bisturi::runtime
