#include <algorithm>
#include <cmath>
#include <limits>

#include "bisturi/scene/volume/volume_io.h"

namespace bisturi {

ValueRange value_range(const Volume& volume) {
  ValueRange r;
  float lo = std::numeric_limits<float>::infinity();
  float hi = -std::numeric_limits<float>::infinity();
  std::size_t n = 0;
  for (const float v : volume.values) {
    if (!std::isfinite(v)) continue;
    lo = std::min(lo, v);
    hi = std::max(hi, v);
    ++n;
  }
  r.finite_count = n;
  r.min = n > 0 ? lo : std::numeric_limits<float>::quiet_NaN();
  r.max = n > 0 ? hi : std::numeric_limits<float>::quiet_NaN();
  return r;
}

const char* to_string(VolumeFormat format) {
  switch (format) {
    case VolumeFormat::Nrrd:
      return "NRRD";
    case VolumeFormat::Nifti:
      return "NIfTI-1";
    case VolumeFormat::DicomSeries:
      return "DICOM series";
  }
  return "unknown";
}

}  // namespace bisturi
