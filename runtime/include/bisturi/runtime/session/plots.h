#pragma once
// The session report's pictures, drawn with Cairo into PNG files: a histogram of timing samples
// (haptic period, frame time, latencies) and a time series (force over time).

#include <filesystem>
#include <span>
#include <string>
#include <vector>

namespace bisturi::runtime {

struct PlotStyle {
  int width = 900;
  int height = 420;
};

/// Histogram of `samples` with `bins` bins between their min and max (or [lo, hi] when lo < hi),
/// with the p50 and p99 marked. Throws SceneError-like std::runtime_error naming the file when
/// it cannot be written.
void write_histogram_png(const std::filesystem::path& file, const std::string& title,
                         const std::string& unit, std::span<const double> samples, int bins = 60,
                         double lo = 0.0, double hi = 0.0, const PlotStyle& style = {});

struct Series {
  std::string label;
  std::vector<double> y;
  double r = 0.1, g = 0.3, b = 0.8;  ///< line colour
};

/// Line plot of one or more series over shared x values (e.g. seconds), with axes, ticks and a
/// legend; a horizontal dashed line at `limit` when it is not NaN (e.g. the device's force limit).
void write_series_png(const std::filesystem::path& file, const std::string& title,
                      const std::string& x_label, const std::string& y_label,
                      std::span<const double> x, std::span<const Series> series, double limit,
                      const PlotStyle& style = {});

}  // namespace bisturi::runtime
