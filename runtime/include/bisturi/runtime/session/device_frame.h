#pragma once
// Where a haptic device sits in the scene: the rigid transform from the device's own frame (its
// driver's poses and force vectors) to the scene's world frame, set per device in the scene file
// (`device_to_scene_rotation_deg`, `device_to_scene_translation_mm`; config/README.md). Poses come
// in through it, force vectors go out through its inverse rotation.

#include <glm/gtc/quaternion.hpp>
#include <glm/mat3x3.hpp>
#include <glm/vec3.hpp>

#include "bisturi/devices/device.h"
#include "bisturi/devices/simulated.h"
#include "bisturi/runtime/session/scene_description.h"

namespace bisturi::runtime {

class DeviceFrame {
 public:
  DeviceFrame() = default;
  /// rotation_deg: about the scene's x, then y, then z axis (fixed axes); translation in metres.
  DeviceFrame(const glm::dvec3& rotation_deg, const glm::dvec3& translation_m);

  /// A device pose in the scene frame.
  [[nodiscard]] devices::Pose to_scene(const devices::Pose& device_pose) const;
  /// Every end effector pose of a haptic state in the scene frame (the rest is copied).
  void to_scene(const devices::HapticState& device_state, devices::HapticState& scene_state) const;
  /// A scene pose in the device's frame (the inverse of to_scene).
  [[nodiscard]] devices::Pose to_device(const devices::Pose& scene_pose) const;
  /// A script written in scene coordinates (a procedure's) as the device itself would move: its
  /// poses through to_device. A twin following it reports what the real device would in the
  /// same place, so the session's to_scene brings it back to the scene's path.
  [[nodiscard]] devices::DeviceScript script_to_device(devices::DeviceScript scene_script) const;
  /// A scene-frame force vector in the device's frame (rotation only: forces are free vectors).
  [[nodiscard]] glm::dvec3 force_to_device(const glm::dvec3& scene_force_N) const;
  [[nodiscard]] bool identity() const { return identity_; }

 private:
  glm::dquat rotation_{1.0, 0.0, 0.0, 0.0};  ///< device -> scene
  glm::dmat3 to_device_{1.0};                ///< scene -> device (the inverse rotation)
  glm::dvec3 translation_m_{0.0};
  bool identity_ = true;
};

/// The frame a scene gives a device (device_to_scene_rotation_deg, device_to_scene_translation_mm).
DeviceFrame device_frame_of(const DeviceDescription& device);

}  // namespace bisturi::runtime
