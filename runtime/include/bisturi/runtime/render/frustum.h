#pragma once
// View-frustum tests and screen-space error, the two decisions of culling and level of detail.

#include <array>
#include <limits>

#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>
#include <glm/vec4.hpp>

namespace bisturi::render {

struct Aabb {
  glm::dvec3 lo{std::numeric_limits<double>::infinity()};
  glm::dvec3 hi{-std::numeric_limits<double>::infinity()};

  [[nodiscard]] bool empty() const { return lo.x > hi.x; }
  void extend(const glm::dvec3& p);
  void extend(const Aabb& b);
  [[nodiscard]] Aabb transformed(const glm::dmat4& m) const;
};

enum class Visibility { Outside, Intersects, Inside };

/// Six planes (a, b, c, d), a x + b y + c z + d >= 0 inside, from a view-projection matrix with
/// Vulkan depth (0..1).
struct Frustum {
  std::array<glm::dvec4, 6> planes{};

  static Frustum from_view_projection(const glm::dmat4& view_projection);
  [[nodiscard]] Visibility classify(const Aabb& box) const;
};

/// Distance from a point to a box (0 inside).
double distance_to(const Aabb& box, const glm::dvec3& p);

/// Pixels covered by a length `error_mm` seen at `distance_mm` with `pixels_per_tangent` pixels
/// per unit of view-plane tangent (eye_height / (tan up - tan down)).
double projected_error_px(double error_mm, double distance_mm, double pixels_per_tangent);

}  // namespace bisturi::render
