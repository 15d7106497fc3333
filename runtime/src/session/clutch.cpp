// The arm's clutch (see clutch.h).

#include "clutch.h"

namespace bisturi::runtime {

bool Clutch::apply(devices::HapticState& scene_state) {
  if (buttons_ == 0) return false;
  const bool pressed = (scene_state.buttons & buttons_) != 0;
  scene_state.buttons &= ~buttons_;
  if (scene_state.end_effector_poses.empty()) return held_ = pressed;
  devices::Vec3& p = scene_state.end_effector_poses.front().position_m;
  const glm::dvec3 handle(p.x, p.y, p.z);
  if (pressed && !held_) held_at_m_ = handle + offset_m_;
  if (!pressed && held_) offset_m_ = held_at_m_ - handle;  // follow again from where it stayed
  held_ = pressed;
  const glm::dvec3 instrument = held_ ? held_at_m_ : handle + offset_m_;
  p = {instrument.x, instrument.y, instrument.z};
  return held_;
}

}  // namespace bisturi::runtime
