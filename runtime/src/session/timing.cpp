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
  // A thinning of capacity/2 moves lasts at most capacity/(2 * kMovesPerRecord) + 1 records,
  // of which every other one at most keeps its sample (the rate is halved first).
  arriving_.reserve(capacity_ / (4 * kMovesPerRecord) + 4);
}

void TimingRecorder::record(double value) {
  if (count_ == 0) {
    max_ = min_ = value;
  } else {
    max_ = std::max(max_, value);
    min_ = std::min(min_, value);
  }
  sum_ += value;
  if (thinning_) thin(kMovesPerRecord);
  if (count_ % stride_ == 0) {
    if (!thinning_ && samples_.size() == capacity_) {
      // Full: keep every other sample, a few more each record, and halve the rate from now on.
      thinning_ = true;
      thinned_ = 0;
      stride_ *= 2;
      thin(kMovesPerRecord);
    }
    if (count_ % stride_ == 0) (thinning_ ? arriving_ : samples_).push_back(value);
  }
  ++count_;
}

void TimingRecorder::thin(std::size_t moves) const {
  const std::size_t kept = (samples_.size() + 1) / 2;
  for (; moves > 0 && thinned_ < kept; --moves, ++thinned_)
    samples_[thinned_] = samples_[2 * thinned_];
  if (thinned_ < kept) return;
  samples_.resize(kept);
  samples_.insert(samples_.end(), arriving_.begin(), arriving_.end());  // within the reserve
  arriving_.clear();
  thinning_ = false;
}

const std::vector<double>& TimingRecorder::samples() const {
  if (thinning_) thin(samples_.size());
  return samples_;
}

TimingSummary TimingRecorder::summary() const {
  TimingSummary s;
  s.count = count_;
  if (count_ == 0) return s;
  s.mean = sum_ / static_cast<double>(count_);
  s.max = max_;
  s.min = min_;
  std::vector<double> sorted = samples();
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
