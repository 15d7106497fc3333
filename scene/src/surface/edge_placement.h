#pragma once
// Marching cubes (marching_cubes.cpp): where the vertex of a crossed grid edge goes, as a
// parameter along the edge (VertexPlacement: linear, or the root of the cubic through the grid
// line's four samples), and the index-to-world map that turns it into a position.

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume.h"

namespace bisturi::surface {

class EdgePlacement {
 public:
  /// Vertices stay this far (in edge parameter) from the samples, so that no two coincide and no
  /// edge has zero length where samples equal the iso value.
  static constexpr double kEdgeEps = 1e-3;

  EdgePlacement(const Grid<float>& volume, const IsoSurfaceOptions& options)
      : geometry_(volume.geometry), iso_(options.iso), options_(options) {
    for (int a = 0; a < 3; ++a) {
      axes_[static_cast<std::size_t>(a)] = geometry_.direction[a] * geometry_.spacing[a];
    }
  }

  /// The world position of continuous index coordinates (i, j, k).
  [[nodiscard]] glm::dvec3 world(double i, double j, double k) const {
    return geometry_.origin + axes_[0] * i + axes_[1] * j + axes_[2] * k;
  }

  /// The parameter of the crossed edge from sample p[0] to p[stride]; `index` is p's index along
  /// the edge's axis, `n` the samples along it (for the outer samples of the cubic).
  [[nodiscard]] double parameter(const float* p, std::int64_t stride, std::int64_t index,
                                 std::int64_t n) const {
    const double linear = linear_parameter(p[0], p[stride]);
    if (options_.placement == VertexPlacement::Linear) return linear;
    const double iso = double(iso_);
    const double g1 = double(p[0]) - iso, g2 = double(p[stride]) - iso;
    const bool has0 = index > 0, has3 = index + 2 < n;
    double g0 = has0 ? double(p[-stride]) - iso : 0.0;
    double g3 = has3 ? double(p[2 * stride]) - iso : 0.0;
    if (!std::isfinite(g1) || !std::isfinite(g2) || !std::isfinite(g0) || !std::isfinite(g3)) {
      return linear;
    }
    // p(t) = a + b t + c t^2 + d t^3 through the available samples.
    double b = 0.0, c = 0.0, d = 0.0;
    if (has0 && has3) {
      b = -g0 / 3.0 - g1 / 2.0 + g2 - g3 / 6.0;
      c = (g0 + g2) / 2.0 - g1;
      d = (g3 - g0) / 6.0 + (g1 - g2) / 2.0;
    } else if (has3) {
      b = (-3.0 * g1 + 4.0 * g2 - g3) / 2.0;
      c = (g1 - 2.0 * g2 + g3) / 2.0;
    } else if (has0) {
      b = (g2 - g0) / 2.0;
      c = (g0 + g2) / 2.0 - g1;
    } else {
      return linear;
    }
    const auto value = [&](double t) { return g1 + t * (b + t * (c + t * d)); };
    // Bracket [lo, hi] with value(lo) on g1's side (<= 0 is outside, as the classification).
    double lo = 0.0, hi = 1.0;
    const bool rising = g1 <= 0.0;
    double t = std::clamp(linear, 0.0, 1.0);
    for (int it = 0; it < 40; ++it) {
      const double v = value(t);
      if (v == 0.0) break;
      if ((v < 0.0) == rising) {
        lo = t;
      } else {
        hi = t;
      }
      const double slope = b + t * (2.0 * c + t * 3.0 * d);
      double next = slope != 0.0 ? t - v / slope : 0.5 * (lo + hi);
      if (!(next > std::min(lo, hi) && next < std::max(lo, hi))) next = 0.5 * (lo + hi);
      if (std::abs(next - t) < 1e-13) {
        t = next;
        break;
      }
      t = next;
    }
    return std::clamp(t, kEdgeEps, 1.0 - kEdgeEps);
  }

 private:
  /// The root of the line through (0, a) and (1, b), kept inside the edge; 0.5 where the root is
  /// undefined (NaN or infinite samples).
  [[nodiscard]] double linear_parameter(float a, float b) const {
    const double t = (double(iso_) - double(a)) / (double(b) - double(a));
    if (!(t >= kEdgeEps)) return std::isfinite(t) && t < kEdgeEps ? kEdgeEps : 0.5;
    return std::min(t, 1.0 - kEdgeEps);
  }

  const VolumeGeometry& geometry_;
  float iso_;
  const IsoSurfaceOptions& options_;  // for the placement
  std::array<glm::dvec3, 3> axes_{};  // index step along i, j, k in world millimetres
};

}  // namespace bisturi::surface
