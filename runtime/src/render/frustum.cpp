#include "bisturi/runtime/render/frustum.h"

#include <algorithm>
#include <cmath>

namespace bisturi::render {

void Aabb::extend(const glm::dvec3& p) {
  lo = glm::min(lo, p);
  hi = glm::max(hi, p);
}

void Aabb::extend(const Aabb& b) {
  if (b.empty()) return;
  lo = glm::min(lo, b.lo);
  hi = glm::max(hi, b.hi);
}

Aabb Aabb::transformed(const glm::dmat4& m) const {
  Aabb out;
  if (empty()) return out;
  for (int i = 0; i < 8; ++i) {
    const glm::dvec3 corner((i & 1) ? hi.x : lo.x, (i & 2) ? hi.y : lo.y, (i & 4) ? hi.z : lo.z);
    out.extend(glm::dvec3(m * glm::dvec4(corner, 1.0)));
  }
  return out;
}

Frustum Frustum::from_view_projection(const glm::dmat4& m) {
  const auto row = [&m](int i) { return glm::dvec4(m[0][i], m[1][i], m[2][i], m[3][i]); };
  Frustum f;
  f.planes = {row(3) + row(0), row(3) - row(0), row(3) + row(1),
              row(3) - row(1), row(2),          row(3) - row(2)};
  for (glm::dvec4& p : f.planes) {
    const double n = glm::length(glm::dvec3(p));
    if (n > 0.0) p /= n;
  }
  return f;
}

Visibility Frustum::classify(const Aabb& box) const {
  if (box.empty()) return Visibility::Outside;
  Visibility result = Visibility::Inside;
  for (const glm::dvec4& p : planes) {
    const glm::dvec3 n(p);
    // The corner farthest along the plane normal, and the nearest one.
    const glm::dvec3 far_corner(n.x >= 0 ? box.hi.x : box.lo.x, n.y >= 0 ? box.hi.y : box.lo.y,
                                n.z >= 0 ? box.hi.z : box.lo.z);
    const glm::dvec3 near_corner(n.x >= 0 ? box.lo.x : box.hi.x, n.y >= 0 ? box.lo.y : box.hi.y,
                                 n.z >= 0 ? box.lo.z : box.hi.z);
    if (glm::dot(n, far_corner) + p.w < 0.0) return Visibility::Outside;
    if (glm::dot(n, near_corner) + p.w < 0.0) result = Visibility::Intersects;
  }
  return result;
}

double distance_to(const Aabb& box, const glm::dvec3& p) {
  if (box.empty()) return 0.0;
  const glm::dvec3 d = glm::max(glm::max(box.lo - p, p - box.hi), glm::dvec3(0.0));
  return glm::length(d);
}

double projected_error_px(double error_mm, double distance_mm, double pixels_per_tangent) {
  if (error_mm <= 0.0) return 0.0;
  if (distance_mm <= 0.0) return std::numeric_limits<double>::infinity();
  return error_mm / distance_mm * pixels_per_tangent;
}

}  // namespace bisturi::render
