#include "bisturi/runtime/session/plots.h"

#include <cairo.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <memory>
#include <stdexcept>

#include "bisturi/runtime/session/timing.h"

namespace bisturi::runtime {

namespace {

struct Surface {
  explicit Surface(const PlotStyle& style)
      : surface(cairo_image_surface_create(CAIRO_FORMAT_ARGB32, style.width, style.height),
                cairo_surface_destroy),
        cr(cairo_create(surface.get()), cairo_destroy) {
    cairo_set_source_rgb(cr.get(), 1, 1, 1);
    cairo_paint(cr.get());
  }
  void save(const std::filesystem::path& file) {
    cairo_surface_flush(surface.get());
    if (cairo_surface_write_to_png(surface.get(), file.c_str()) != CAIRO_STATUS_SUCCESS) {
      throw std::runtime_error(file.string() + ": cannot write the plot");
    }
  }
  std::unique_ptr<cairo_surface_t, decltype(&cairo_surface_destroy)> surface;
  std::unique_ptr<cairo_t, decltype(&cairo_destroy)> cr;
};

/// The plotting area inside the margins, and the maps from data to pixels.
struct Frame {
  double left = 70, right = 20, top = 40, bottom = 50;
  double width = 0, height = 0;
  double x0 = 0, x1 = 1, y0 = 0, y1 = 1;
  [[nodiscard]] double px(double x) const { return left + (x - x0) / (x1 - x0) * width; }
  [[nodiscard]] double py(double y) const { return top + height - (y - y0) / (y1 - y0) * height; }
};

std::string format_tick(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.4g", v);
  return buf;
}

/// A "nice" tick step (1, 2 or 5 times a power of ten) for about `count` ticks over `span`.
double tick_step(double span, int count) {
  const double raw = span / std::max(count, 1);
  const double mag = std::pow(10.0, std::floor(std::log10(raw)));
  const double norm = raw / mag;
  return (norm < 1.5 ? 1.0 : norm < 3.5 ? 2.0 : norm < 7.5 ? 5.0 : 10.0) * mag;
}

void draw_axes(cairo_t* cr, const Frame& f, const std::string& title, const std::string& x_label,
               const std::string& y_label) {
  cairo_set_source_rgb(cr, 0, 0, 0);
  cairo_set_line_width(cr, 1.0);
  cairo_rectangle(cr, f.left, f.top, f.width, f.height);
  cairo_stroke(cr);
  cairo_select_font_face(cr, "sans-serif", CAIRO_FONT_SLANT_NORMAL, CAIRO_FONT_WEIGHT_NORMAL);
  cairo_set_font_size(cr, 11);
  for (int axis = 0; axis < 2; ++axis) {
    const double lo = axis == 0 ? f.x0 : f.y0;
    const double hi = axis == 0 ? f.x1 : f.y1;
    const double step = tick_step(hi - lo, axis == 0 ? 8 : 5);
    for (double v = std::ceil(lo / step) * step; v <= hi + 1e-9 * step; v += step) {
      const std::string text = format_tick(std::abs(v) < 1e-12 * step ? 0.0 : v);
      cairo_text_extents_t ext;
      cairo_text_extents(cr, text.c_str(), &ext);
      if (axis == 0) {
        const double x = f.px(v);
        cairo_move_to(cr, x, f.top + f.height);
        cairo_line_to(cr, x, f.top + f.height + 4);
        cairo_stroke(cr);
        cairo_move_to(cr, x - ext.width / 2, f.top + f.height + 17);
      } else {
        const double y = f.py(v);
        cairo_move_to(cr, f.left - 4, y);
        cairo_line_to(cr, f.left, y);
        cairo_stroke(cr);
        cairo_move_to(cr, f.left - 8 - ext.width, y + ext.height / 2);
      }
      cairo_show_text(cr, text.c_str());
    }
  }
  cairo_text_extents_t ext;
  cairo_text_extents(cr, x_label.c_str(), &ext);
  cairo_move_to(cr, f.left + f.width / 2 - ext.width / 2, f.top + f.height + 38);
  cairo_show_text(cr, x_label.c_str());
  cairo_save(cr);
  cairo_text_extents(cr, y_label.c_str(), &ext);
  cairo_move_to(cr, 18, f.top + f.height / 2 + ext.width / 2);
  cairo_rotate(cr, -M_PI / 2);
  cairo_show_text(cr, y_label.c_str());
  cairo_restore(cr);
  cairo_set_font_size(cr, 14);
  cairo_move_to(cr, f.left, 24);
  cairo_show_text(cr, title.c_str());
}

Frame make_frame(const PlotStyle& style) {
  Frame f;
  f.width = style.width - f.left - f.right;
  f.height = style.height - f.top - f.bottom;
  return f;
}

}  // namespace

void write_histogram_png(const std::filesystem::path& file, const std::string& title,
                         const std::string& unit, std::span<const double> samples, int bins,
                         double lo, double hi, const PlotStyle& style) {
  bins = std::max(bins, 1);
  std::vector<double> finite;
  finite.reserve(samples.size());
  for (double v : samples) {
    if (std::isfinite(v)) finite.push_back(v);
  }
  if (!(lo < hi)) {
    lo = finite.empty() ? 0.0 : *std::min_element(finite.begin(), finite.end());
    hi = finite.empty() ? 1.0 : *std::max_element(finite.begin(), finite.end());
    if (!(lo < hi)) {
      lo -= 0.5;
      hi += 0.5;
    }
  }
  std::vector<double> counts(static_cast<std::size_t>(bins), 0.0);
  for (double v : finite) {
    const auto b = static_cast<std::ptrdiff_t>(std::floor((v - lo) / (hi - lo) * bins));
    counts[static_cast<std::size_t>(std::clamp<std::ptrdiff_t>(b, 0, bins - 1))] += 1.0;
  }
  Surface s(style);
  Frame f = make_frame(style);
  f.x0 = lo;
  f.x1 = hi;
  f.y0 = 0.0;
  f.y1 = std::max(1.0, *std::max_element(counts.begin(), counts.end()) * 1.1);
  cairo_t* cr = s.cr.get();
  cairo_set_source_rgb(cr, 0.25, 0.45, 0.75);
  const double bin_width = (hi - lo) / bins;
  for (int b = 0; b < bins; ++b) {
    const double c = counts[static_cast<std::size_t>(b)];
    if (c <= 0.0) continue;
    const double x = f.px(lo + b * bin_width);
    const double w = f.px(lo + (b + 1) * bin_width) - x;
    cairo_rectangle(cr, x, f.py(c), std::max(w - 0.5, 0.5), f.py(0.0) - f.py(c));
  }
  cairo_fill(cr);
  // p50 and p99 as vertical lines.
  const double marks[2] = {percentile(finite, 50.0), percentile(finite, 99.0)};
  const char* names[2] = {"p50", "p99"};
  cairo_set_font_size(cr, 11);
  for (int m = 0; m < 2 && !finite.empty(); ++m) {
    cairo_set_source_rgb(cr, m == 0 ? 0.1 : 0.8, m == 0 ? 0.6 : 0.1, 0.1);
    const double x = f.px(std::clamp(marks[m], lo, hi));
    cairo_move_to(cr, x, f.top);
    cairo_line_to(cr, x, f.top + f.height);
    cairo_stroke(cr);
    const std::string text = std::string(names[m]) + " " + format_tick(marks[m]);
    cairo_move_to(cr, x + 4, f.top + 14 + 14 * m);
    cairo_show_text(cr, text.c_str());
  }
  draw_axes(cr, f, title + " (" + std::to_string(finite.size()) + " samples)", unit, "count");
  s.save(file);
}

void write_series_png(const std::filesystem::path& file, const std::string& title,
                      const std::string& x_label, const std::string& y_label,
                      std::span<const double> x, std::span<const Series> series, double limit,
                      const PlotStyle& style) {
  Surface s(style);
  Frame f = make_frame(style);
  f.x0 = x.empty() ? 0.0 : x.front();
  f.x1 = x.empty() ? 1.0 : x.back();
  if (!(f.x0 < f.x1)) f.x1 = f.x0 + 1.0;
  double ylo = std::numeric_limits<double>::infinity();
  double yhi = -ylo;
  for (const Series& ser : series) {
    for (double v : ser.y) {
      if (!std::isfinite(v)) continue;
      ylo = std::min(ylo, v);
      yhi = std::max(yhi, v);
    }
  }
  if (std::isfinite(limit)) {
    ylo = std::min(ylo, limit);
    yhi = std::max(yhi, limit);
  }
  if (!(ylo < yhi)) {
    ylo = std::isfinite(ylo) ? ylo - 1.0 : 0.0;
    yhi = ylo + 2.0;
  }
  const double pad = 0.05 * (yhi - ylo);
  f.y0 = ylo - pad;
  f.y1 = yhi + pad;
  cairo_t* cr = s.cr.get();
  cairo_set_line_width(cr, 1.2);
  cairo_set_font_size(cr, 11);
  // The legend sits inside the frame's top right corner, as wide as its longest label.
  double label_width = 0.0;
  for (const Series& ser : series) {
    cairo_text_extents_t extents;
    cairo_text_extents(cr, ser.label.c_str(), &extents);
    label_width = std::max(label_width, extents.x_advance);
  }
  const double legend_x = std::max(f.left + 4.0, f.left + f.width - label_width - 35.0);
  double legend_y = f.top + 14;
  for (const Series& ser : series) {
    cairo_set_source_rgb(cr, ser.r, ser.g, ser.b);
    bool pen_down = false;
    const std::size_t n = std::min(x.size(), ser.y.size());
    for (std::size_t i = 0; i < n; ++i) {
      if (!std::isfinite(ser.y[i])) {
        pen_down = false;
        continue;
      }
      if (pen_down) {
        cairo_line_to(cr, f.px(x[i]), f.py(ser.y[i]));
      } else {
        cairo_move_to(cr, f.px(x[i]), f.py(ser.y[i]));
        pen_down = true;
      }
    }
    cairo_stroke(cr);
    cairo_move_to(cr, legend_x, legend_y);
    cairo_line_to(cr, legend_x + 20, legend_y);
    cairo_stroke(cr);
    cairo_move_to(cr, legend_x + 25, legend_y + 4);
    cairo_show_text(cr, ser.label.c_str());
    legend_y += 15;
  }
  if (std::isfinite(limit)) {
    const double dash[] = {6.0, 4.0};
    cairo_set_source_rgb(cr, 0.8, 0.1, 0.1);
    cairo_set_dash(cr, dash, 2, 0);
    cairo_move_to(cr, f.left, f.py(limit));
    cairo_line_to(cr, f.left + f.width, f.py(limit));
    cairo_stroke(cr);
    cairo_set_dash(cr, nullptr, 0, 0);
  }
  draw_axes(cr, f, title, x_label, y_label);
  s.save(file);
}

}  // namespace bisturi::runtime
