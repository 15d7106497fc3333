#include "bisturi/runtime/render/headset.h"

#include <cmath>

#include <glm/gtc/matrix_transform.hpp>
#include <glm/mat3x3.hpp>

namespace bisturi::render {

HeadPose look_at(const glm::dvec3& eye_mm, const glm::dvec3& target_mm, const glm::dvec3& up) {
  const glm::dvec3 forward = glm::normalize(target_mm - eye_mm);
  const glm::dvec3 right = glm::normalize(glm::cross(forward, up));
  const glm::dvec3 true_up = glm::cross(right, forward);
  HeadPose pose;
  pose.position_mm = eye_mm;
  pose.orientation = glm::quat_cast(glm::dmat3(right, true_up, -forward));
  pose.sample_time = PoseClock::now();
  return pose;
}

glm::dmat4 projection_from_fov(const EyeFov& fov, double near_mm, double far_mm) {
  const double tan_left = std::tan(static_cast<double>(fov.angle_left));
  const double tan_right = std::tan(static_cast<double>(fov.angle_right));
  const double tan_up = std::tan(static_cast<double>(fov.angle_up));
  const double tan_down = std::tan(static_cast<double>(fov.angle_down));
  const double width = tan_right - tan_left;
  const double height = tan_down - tan_up;  // negative: Vulkan's clip-space y points down
  glm::dmat4 m(0.0);
  m[0][0] = 2.0 / width;
  m[2][0] = (tan_right + tan_left) / width;
  m[1][1] = 2.0 / height;
  m[2][1] = (tan_up + tan_down) / height;
  m[2][2] = -far_mm / (far_mm - near_mm);  // depth 0 at near, 1 at far
  m[3][2] = -(far_mm * near_mm) / (far_mm - near_mm);
  m[2][3] = -1.0;
  return m;
}

std::array<EyeView, 2> eye_views(const HeadsetDescription& headset, const HeadPose& head) {
  std::array<EyeView, 2> eyes;
  const glm::dmat3 rotation = glm::mat3_cast(glm::normalize(head.orientation));
  for (int e = 0; e < 2; ++e) {
    EyeView& eye = eyes[static_cast<std::size_t>(e)];
    const double side = e == 0 ? -0.5 : 0.5;
    eye.position_mm = head.position_mm + rotation * glm::dvec3(side * headset.ipd_mm, 0.0, 0.0);
    glm::dmat4 eye_to_world(rotation);
    eye_to_world[3] = glm::dvec4(eye.position_mm, 1.0);
    eye.view = glm::inverse(eye_to_world);
    eye.fov = headset.fov[static_cast<std::size_t>(e)];
    eye.projection = projection_from_fov(eye.fov, headset.near_mm, headset.far_mm);
    eye.view_projection = eye.projection * eye.view;
  }
  return eyes;
}

std::array<EyeView, 2> eye_views(const HeadsetDescription& headset,
                                 const std::array<EyePose, 2>& eyes) {
  std::array<EyeView, 2> out;
  for (std::size_t e = 0; e < 2; ++e) {
    EyeView& eye = out[e];
    eye.position_mm = eyes[e].position_mm;
    glm::dmat4 eye_to_world(glm::mat3_cast(glm::normalize(eyes[e].orientation)));
    eye_to_world[3] = glm::dvec4(eye.position_mm, 1.0);
    eye.view = glm::inverse(eye_to_world);
    eye.fov = eyes[e].fov;
    eye.projection = projection_from_fov(eye.fov, headset.near_mm, headset.far_mm);
    eye.view_projection = eye.projection * eye.view;
  }
  return out;
}

}  // namespace bisturi::render
