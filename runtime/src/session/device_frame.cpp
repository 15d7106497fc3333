// A haptic device's frame in the scene (see device_frame.h).

#include "bisturi/runtime/session/device_frame.h"

#include <glm/gtc/matrix_transform.hpp>

namespace bisturi::runtime {

DeviceFrame::DeviceFrame(const glm::dvec3& rotation_deg, const glm::dvec3& translation_m)
    : translation_m_(translation_m) {
  const glm::dvec3 r = glm::radians(rotation_deg);
  // Fixed axes x, then y, then z: R = Rz * Ry * Rx.
  rotation_ = glm::angleAxis(r.z, glm::dvec3(0, 0, 1)) * glm::angleAxis(r.y, glm::dvec3(0, 1, 0)) *
              glm::angleAxis(r.x, glm::dvec3(1, 0, 0));
  to_device_ = glm::transpose(glm::mat3_cast(rotation_));
  identity_ = rotation_deg == glm::dvec3(0.0) && translation_m == glm::dvec3(0.0);
}

devices::Pose DeviceFrame::to_scene(const devices::Pose& device_pose) const {
  if (identity_) return device_pose;
  const glm::dvec3 p(device_pose.position_m.x, device_pose.position_m.y, device_pose.position_m.z);
  const glm::dquat q(device_pose.orientation.w, device_pose.orientation.x,
                     device_pose.orientation.y, device_pose.orientation.z);
  const glm::dvec3 ps = rotation_ * p + translation_m_;
  const glm::dquat qs = rotation_ * q;
  devices::Pose out;
  out.position_m = {ps.x, ps.y, ps.z};
  out.orientation = {qs.w, qs.x, qs.y, qs.z};
  return out;
}

devices::Pose DeviceFrame::to_device(const devices::Pose& scene_pose) const {
  if (identity_) return scene_pose;
  const glm::dvec3 p(scene_pose.position_m.x, scene_pose.position_m.y, scene_pose.position_m.z);
  const glm::dquat q(scene_pose.orientation.w, scene_pose.orientation.x,
                     scene_pose.orientation.y, scene_pose.orientation.z);
  const glm::dvec3 pd = to_device_ * (p - translation_m_);
  const glm::dquat qd = glm::conjugate(rotation_) * q;
  devices::Pose out;
  out.position_m = {pd.x, pd.y, pd.z};
  out.orientation = {qd.w, qd.x, qd.y, qd.z};
  return out;
}

devices::DeviceScript DeviceFrame::script_to_device(devices::DeviceScript scene_script) const {
  for (devices::MotionKey& key : scene_script.motion)
    key.pose = to_device(key.pose);
  return scene_script;
}

void DeviceFrame::to_scene(const devices::HapticState& device_state,
                           devices::HapticState& scene_state) const {
  scene_state.sample_time = device_state.sample_time;
  scene_state.reports = device_state.reports;
  scene_state.buttons = device_state.buttons;
  scene_state.finger_joint_angles_rad.assign(device_state.finger_joint_angles_rad.begin(),
                                             device_state.finger_joint_angles_rad.end());
  scene_state.end_effector_poses.resize(device_state.end_effector_poses.size());
  for (std::size_t i = 0; i < device_state.end_effector_poses.size(); ++i)
    scene_state.end_effector_poses[i] = to_scene(device_state.end_effector_poses[i]);
}

glm::dvec3 DeviceFrame::force_to_device(const glm::dvec3& scene_force_N) const {
  return identity_ ? scene_force_N : to_device_ * scene_force_N;
}

DeviceFrame device_frame_of(const DeviceDescription& device) {
  const auto& r = device.device_to_scene_rotation_deg;
  const auto& t = device.device_to_scene_translation_mm;
  constexpr double kMetresPerMillimetre = 1e-3;
  return DeviceFrame(glm::dvec3(r[0], r[1], r[2]),
                     glm::dvec3(t[0], t[1], t[2]) * kMetresPerMillimetre);
}

}  // namespace bisturi::runtime
