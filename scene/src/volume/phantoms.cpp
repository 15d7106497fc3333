#include "bisturi/scene/volume/phantoms.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "bisturi/scene/errors.h"

namespace bisturi {

namespace {

constexpr PhantomShape kShapes[] = {PhantomShape::Sphere, PhantomShape::Shell,
                                    PhantomShape::Torus,  PhantomShape::TwoSpheres,
                                    PhantomShape::Tube,   PhantomShape::Gyroid};

/// Default sizes: fractions of the half-extent of the smallest side, so every closed shape
/// stays clear of the border by at least two samples.
struct Params {
  double a, b;
};

Params resolve(const PhantomOptions& o, double half) {
  Params p{o.a, o.b};
  switch (o.shape) {
    case PhantomShape::Sphere:
      if (p.a <= 0) p.a = 0.7 * half;
      break;
    case PhantomShape::Shell:
      if (p.a <= 0) p.a = 0.8 * half;
      if (p.b <= 0) p.b = 0.5 * p.a;
      if (p.b >= p.a) throw InputError("shell phantom: inner radius must be below outer radius");
      break;
    case PhantomShape::Torus:
      if (p.a <= 0) p.a = 0.55 * half;
      if (p.b <= 0) p.b = 0.5 * p.a;
      if (p.b >= p.a) throw InputError("torus phantom: minor radius must be below major radius");
      break;
    case PhantomShape::TwoSpheres:
      if (p.a <= 0) p.a = 0.4 * half;
      if (p.b <= 0) p.b = 0.5 * o.spacing.x;  // half a voxel apart: the figure-21 case
      break;
    case PhantomShape::Tube:
      if (p.a <= 0) p.a = 0.5 * half;
      break;
    case PhantomShape::Gyroid:
      if (p.a <= 0) p.a = half / 2.0;
      break;
  }
  return p;
}

}  // namespace

Volume make_phantom(const PhantomOptions& o) {
  for (int axis = 0; axis < 3; ++axis) {
    if (o.dims[axis] < 2 || o.dims[axis] > 4096) {
      throw InputError("phantom: dims must be 2..4096 samples per axis, got " +
                       std::to_string(o.dims[axis]));
    }
    if (!(o.spacing[axis] > 0) || !std::isfinite(o.spacing[axis])) {
      throw InputError("phantom: spacing must be positive and finite");
    }
  }
  Volume v;
  v.geometry.dims = o.dims;
  v.geometry.spacing = o.spacing;
  v.values.resize(v.geometry.voxel_count());
  const glm::dvec3 extent = glm::dvec3(o.dims[0] - 1, o.dims[1] - 1, o.dims[2] - 1) * o.spacing;
  const glm::dvec3 centre = extent * 0.5;
  const double half = std::min({centre.x, centre.y, centre.z});
  const Params p = resolve(o, half);
  const double two_pi = 2.0 * std::numbers::pi;

  std::size_t n = 0;
  for (std::int64_t k = 0; k < o.dims[2]; ++k) {
    for (std::int64_t j = 0; j < o.dims[1]; ++j) {
      for (std::int64_t i = 0; i < o.dims[0]; ++i, ++n) {
        const glm::dvec3 q = glm::dvec3(i, j, k) * o.spacing - centre;
        double d = 0.0;
        switch (o.shape) {
          case PhantomShape::Sphere:
            d = p.a - glm::length(q);
            break;
          case PhantomShape::Shell: {
            const double r = glm::length(q);
            d = std::min(p.a - r, r - p.b);
            break;
          }
          case PhantomShape::Torus: {
            const double ring = std::hypot(q.x, q.y) - p.a;
            d = p.b - std::hypot(ring, q.z);
            break;
          }
          case PhantomShape::TwoSpheres: {
            const double offset = p.a + 0.5 * p.b;
            const double left = p.a - glm::length(q - glm::dvec3(offset, 0, 0));
            const double right = p.a - glm::length(q + glm::dvec3(offset, 0, 0));
            d = std::max(left, right);
            break;
          }
          case PhantomShape::Tube:
            d = p.a - std::hypot(q.x, q.y);
            break;
          case PhantomShape::Gyroid: {
            const glm::dvec3 w = q * (two_pi / p.a);
            const double g = std::sin(w.x) * std::cos(w.y) + std::sin(w.y) * std::cos(w.z) +
                             std::sin(w.z) * std::cos(w.x);
            d = g * p.a / two_pi;  // about millimetres near the surface (|grad g| ~ 2 pi / a)
            break;
          }
        }
        v.values[n] = static_cast<float>(d);
      }
    }
  }
  return v;
}

std::string_view to_string(PhantomShape shape) {
  switch (shape) {
    case PhantomShape::Sphere:
      return "sphere";
    case PhantomShape::Shell:
      return "shell";
    case PhantomShape::Torus:
      return "torus";
    case PhantomShape::TwoSpheres:
      return "two-spheres";
    case PhantomShape::Tube:
      return "tube";
    case PhantomShape::Gyroid:
      return "gyroid";
  }
  return "unknown";
}

PhantomShape phantom_shape_from_string(std::string_view name) {
  for (PhantomShape s : kShapes) {
    if (to_string(s) == name) return s;
  }
  std::string valid;
  for (const std::string& n : phantom_shape_names())
    valid += (valid.empty() ? "" : ", ") + n;
  throw InputError("unknown phantom shape '" + std::string(name) + "' (valid: " + valid + ")");
}

std::vector<std::string> phantom_shape_names() {
  std::vector<std::string> names;
  for (PhantomShape s : kShapes)
    names.emplace_back(to_string(s));
  return names;
}

}  // namespace bisturi
