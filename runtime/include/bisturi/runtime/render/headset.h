#pragma once
// The headset as the renderer sees it, and the two eyes' views and projections.
//
// Units and frames: the renderer works in the scene's world millimetres. A head pose is the
// head's position (mm) and orientation in the world; the head frame is OpenXR's view frame
// (x right, y up, looking down -z). Each eye sits ipd_mm / 2 along the head's x axis. Field-of-view
// angles are OpenXR's (radians, left and down negative), so asymmetric frusta come straight from
// a runtime. Projections are Vulkan's: depth 0 (near) to 1 (far), y down in clip space.

#include <array>
#include <chrono>
#include <cstdint>

#include <glm/gtc/quaternion.hpp>
#include <glm/mat4x4.hpp>
#include <glm/vec3.hpp>

namespace bisturi::render {

struct EyeFov {
  float angle_left = -0.785398f;  ///< radians, negative to the left
  float angle_right = 0.785398f;
  float angle_up = 0.785398f;
  float angle_down = -0.785398f;  ///< radians, negative downwards
};

struct HeadsetDescription {
  double ipd_mm = 64.0;
  std::array<EyeFov, 2> fov{};  ///< left eye, right eye
  std::uint32_t eye_width = 1024;
  std::uint32_t eye_height = 1024;
  double near_mm = 10.0;
  double far_mm = 5000.0;
};

using PoseClock = std::chrono::steady_clock;

struct HeadPose {
  glm::dvec3 position_mm{0.0};
  glm::dquat orientation{1.0, 0.0, 0.0, 0.0};  ///< head frame to world
  /// When the tracker sampled this pose: motion-to-photon latency is measured from here.
  PoseClock::time_point sample_time{};
  /// When the frame drawn for this pose will be shown: an OpenXR runtime's predicted display
  /// time; zero when the frame is shown as soon as it is finished (files, tests).
  PoseClock::time_point display_time{};
};

/// One eye as a runtime locates it: where it is and how it looks in the world (mm; the eye frame
/// is OpenXR's view frame) and its field of view.
struct EyePose {
  glm::dvec3 position_mm{0.0};
  glm::dquat orientation{1.0, 0.0, 0.0, 0.0};  ///< eye frame to world
  EyeFov fov{};
};

/// A pose at `eye_mm` looking at `target_mm` with `up` (world) roughly up.
HeadPose look_at(const glm::dvec3& eye_mm, const glm::dvec3& target_mm,
                 const glm::dvec3& up = {0.0, 1.0, 0.0});

struct EyeView {
  glm::dvec3 position_mm{0.0};
  glm::dmat4 view{1.0};        ///< world to eye
  glm::dmat4 projection{1.0};  ///< eye to clip (Vulkan)
  glm::dmat4 view_projection{1.0};
  EyeFov fov{};
};

/// The projection of an asymmetric frustum (OpenXR angles) for Vulkan clip space.
glm::dmat4 projection_from_fov(const EyeFov& fov, double near_mm, double far_mm);

/// Views of the left (0) and right (1) eye for a head pose.
std::array<EyeView, 2> eye_views(const HeadsetDescription& headset, const HeadPose& head);

/// Views of eyes a runtime located (their own poses and fields of view); the headset gives the
/// depth range only.
std::array<EyeView, 2> eye_views(const HeadsetDescription& headset,
                                 const std::array<EyePose, 2>& eyes);

}  // namespace bisturi::render
