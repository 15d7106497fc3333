// Thresholds, CT windows and label indicators.

#include <cmath>
#include <cstddef>
#include <string>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/segmentation.h"
#include "checks.h"

namespace bisturi {

using segmentation_detail::check_grid;

IntensityRange window_range(float centre, float width) {
  if (!std::isfinite(centre) || !std::isfinite(width) || width < 0) {
    throw InputError("window: centre " + std::to_string(centre) + " and width " +
                     std::to_string(width) + " must be finite, the width not negative");
  }
  return {centre - width / 2, centre + width / 2};
}

Grid<std::uint8_t> threshold(const Volume& volume, float lo, float hi) {
  check_grid(volume, "threshold");
  if (std::isnan(lo) || std::isnan(hi) || lo > hi) {
    throw InputError("threshold: range [" + std::to_string(lo) + ", " + std::to_string(hi) +
                     "] is empty or not a number");
  }
  Grid<std::uint8_t> mask;
  mask.geometry = volume.geometry;
  const std::size_t n = volume.values.size();
  mask.values.resize(n);
  const float* v = volume.values.data();
  std::uint8_t* m = mask.values.data();
  for (std::size_t i = 0; i < n; ++i)
    m[i] = (v[i] >= lo && v[i] <= hi) ? 1 : 0;
  return mask;
}

Grid<float> label_indicator(const LabelVolume& labels, std::uint32_t label) {
  check_grid(labels, "label indicator");
  Grid<float> out;
  out.geometry = labels.geometry;
  const std::size_t n = labels.values.size();
  out.values.resize(n);
  const std::uint32_t* l = labels.values.data();
  float* o = out.values.data();
  for (std::size_t i = 0; i < n; ++i)
    o[i] = l[i] == label ? 1.0F : 0.0F;
  return out;
}

Volume label_indicator_volume(const LabelVolume& labels, std::uint32_t label) {
  Volume out;
  static_cast<Grid<float>&>(out) = label_indicator(labels, label);
  return out;
}

}  // namespace bisturi
