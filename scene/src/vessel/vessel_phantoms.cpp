#include "bisturi/scene/vessel/vessel_phantoms.h"

#include <algorithm>
#include <cmath>
#include <numbers>
#include <random>

#include <glm/geometric.hpp>
#include <glm/mat3x3.hpp>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

constexpr double kPi = std::numbers::pi;

struct Nearest {
  double t = 0.0;
  double distance = 0.0;
  glm::dvec3 point{0.0};
};

Nearest nearest_on(const AxisPiece& s, const glm::dvec3& p) {
  const glm::dvec3 ab = s.b - s.a;
  const double len2 = glm::dot(ab, ab);
  const double t = len2 > 0.0 ? std::clamp(glm::dot(p - s.a, ab) / len2, 0.0, 1.0) : 0.0;
  const glm::dvec3 q = s.a + t * ab;
  return {t, glm::distance(p, q), q};
}

glm::dmat3 rotation(double degrees) {
  const double a = degrees * kPi / 180.0, b = 0.7 * a;
  const glm::dmat3 rx(1, 0, 0, 0, std::cos(a), std::sin(a), 0, -std::sin(a), std::cos(a));
  const glm::dmat3 ry(std::cos(b), 0, -std::sin(b), 0, 1, 0, std::sin(b), 0, std::cos(b));
  return ry * rx;
}

void check_positive(double v, const char* what) {
  if (!(v > 0.0) || !std::isfinite(v)) {
    throw InputError(std::string("vessel phantom: ") + what + " must be positive and finite");
  }
}

}  // namespace

AxisNearest VesselPhantom::nearest(const glm::dvec3& p) const {
  AxisNearest best;
  best.distance_mm = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < axis.size(); ++i) {
    const Nearest n = nearest_on(axis[i], p);
    if (n.distance < best.distance_mm) {
      best.distance_mm = n.distance;
      best.point = n.point;
      best.piece = i;
      best.radius_mm = (1.0 - n.t) * axis[i].radius_a + n.t * axis[i].radius_b;
    }
  }
  return best;
}

VesselPhantom make_vessel_phantom(const VesselPhantomOptions& o) {
  check_positive(o.radius_mm, "the radius");
  check_positive(o.length_mm, "the length");
  for (int a = 0; a < 3; ++a)
    check_positive(o.spacing[a], "the spacing");
  const double end_radius = o.end_radius_mm > 0.0
                                ? o.end_radius_mm
                                : (o.shape == VesselShape::Tapering ? 0.5 : 0.7) * o.radius_mm;
  VesselPhantom ph;
  std::vector<AxisPiece> local;
  switch (o.shape) {
    case VesselShape::Straight:
      local.push_back({{0, 0, 0}, {0, 0, o.length_mm}, o.radius_mm, o.radius_mm});
      break;
    case VesselShape::Tapering:
      local.push_back({{0, 0, 0}, {0, 0, o.length_mm}, o.radius_mm, end_radius});
      break;
    case VesselShape::Curved: {
      check_positive(o.bend_radius_mm, "the bend radius");
      const double sweep = o.length_mm / o.bend_radius_mm;
      const int n = std::max(2, static_cast<int>(std::ceil(sweep * 180.0 / kPi)));
      const double R = o.bend_radius_mm;
      const auto at = [&](double th) {
        return glm::dvec3(R - R * std::cos(th), 0.0, R * std::sin(th));
      };
      for (int i = 0; i < n; ++i) {
        local.push_back({at(sweep * i / n), at(sweep * (i + 1) / n), o.radius_mm, o.radius_mm});
      }
      break;
    }
    case VesselShape::Bifurcating: {
      const double half = 0.5 * o.length_mm;
      const glm::dvec3 j(0, 0, half);
      const double s = o.spread_degrees * kPi / 180.0;
      local.push_back({{0, 0, 0}, j, o.radius_mm, o.radius_mm});
      ph.branch_first_piece = {0, 1, 2};
      local.push_back(
          {j, j + half * glm::dvec3(std::sin(s), 0, std::cos(s)), end_radius, end_radius});
      local.push_back(
          {j, j + half * glm::dvec3(-std::sin(s), 0, std::cos(s)), end_radius, end_radius});
      break;
    }
  }
  if (ph.branch_first_piece.empty()) ph.branch_first_piece = {0};
  check_positive(end_radius, "the end radius");

  // Tilt, then place the bounding box (plus a margin where the edge has faded) at the origin.
  const glm::dmat3 r = rotation(o.tilt_degrees);
  const double hmax = std::max({o.spacing.x, o.spacing.y, o.spacing.z});
  const double edge = o.edge_mm > 0.0 ? o.edge_mm : 1.5 * hmax;
  const double rmax = std::max(o.radius_mm, end_radius);
  const double margin = rmax + 3.0 * edge + 2.0 * hmax;
  glm::dvec3 lo(std::numeric_limits<double>::infinity()), hi(-lo);
  for (AxisPiece& p : local) {
    p.a = r * p.a;
    p.b = r * p.b;
    lo = glm::min(lo, glm::min(p.a, p.b));
    hi = glm::max(hi, glm::max(p.a, p.b));
  }
  lo -= glm::dvec3(margin);
  hi += glm::dvec3(margin);
  for (int a = 0; a < 3; ++a) {
    const double grow = 0.5 * std::max(0.0, o.field_of_view_mm[a] - (hi[a] - lo[a]));
    lo[a] -= grow;
    hi[a] += grow;
  }
  Volume& v = ph.volume;
  v.modality = "CT";
  v.geometry.spacing = o.spacing;
  v.geometry.origin = o.origin;
  for (int a = 0; a < 3; ++a) {
    v.geometry.dims[static_cast<std::size_t>(a)] =
        static_cast<std::int64_t>(std::ceil((hi[a] - lo[a]) / o.spacing[a])) + 1;
    if (v.geometry.dims[static_cast<std::size_t>(a)] > 2048) {
      throw InputError("vessel phantom: more than 2048 samples along an axis");
    }
  }
  for (AxisPiece& p : local) {
    p.a += o.origin - lo;
    p.b += o.origin - lo;
  }
  ph.axis = local;
  ph.mid_hu = 0.5 * (o.lumen_hu + o.background_hu);

  v.values.resize(v.geometry.voxel_count());
  std::mt19937 rng(o.seed);
  std::normal_distribution<double> gauss(0.0, 1.0);
  std::size_t n = 0;
  for (std::int64_t k = 0; k < v.geometry.dims[2]; ++k)
    for (std::int64_t j = 0; j < v.geometry.dims[1]; ++j)
      for (std::int64_t i = 0; i < v.geometry.dims[0]; ++i, ++n) {
        const glm::dvec3 p = v.geometry.index_to_world(glm::dvec3(i, j, k));
        double d = -std::numeric_limits<double>::infinity();
        for (const AxisPiece& s : ph.axis) {
          const Nearest q = nearest_on(s, p);
          d = std::max(d, (1.0 - q.t) * s.radius_a + q.t * s.radius_b - q.distance);
        }
        double value =
            o.background_hu + (o.lumen_hu - o.background_hu) * 0.5 * (1.0 + std::tanh(d / edge));
        if (o.noise_hu > 0.0) value += o.noise_hu * gauss(rng);
        v.values[n] = static_cast<float>(value);
      }
  return ph;
}

std::string_view to_string(VesselShape shape) {
  switch (shape) {
    case VesselShape::Straight:
      return "straight";
    case VesselShape::Curved:
      return "curved";
    case VesselShape::Tapering:
      return "tapering";
    case VesselShape::Bifurcating:
      return "bifurcating";
  }
  return "unknown";
}

VesselShape vessel_shape_from_string(std::string_view name) {
  for (VesselShape s : {VesselShape::Straight, VesselShape::Curved, VesselShape::Tapering,
                        VesselShape::Bifurcating}) {
    if (to_string(s) == name) return s;
  }
  throw InputError("unknown vessel shape '" + std::string(name) +
                   "' (valid: straight, curved, tapering, bifurcating)");
}

}  // namespace bisturi
