#pragma once
// The clutch of a grounded arm: while a clutch button is held the instrument stays where it is
// and the hand moves the handle freely (to re-centre it in the device's workspace); released,
// the instrument follows the handle again from where it stayed. Its forces are zero while held,
// as a clutched arm's motors are. Translation only: the instrument keeps following the handle's
// orientation. The same on live ticks and on replay (it works on the recorded inputs).

#include <cstdint>

#include <glm/vec3.hpp>

#include "bisturi/devices/device.h"

namespace bisturi::runtime {

class Clutch {
 public:
  /// `buttons`: the bits of the clutch buttons (0: no clutch).
  explicit Clutch(std::uint64_t buttons = 0) : buttons_(buttons) {}
  /// Takes the device's state in the scene frame and moves its first end effector by the offset
  /// the clutch has built up (held: to where it stayed). The clutch buttons are taken out of
  /// the state's buttons. Returns whether the clutch is held now.
  bool apply(devices::HapticState& scene_state);
  [[nodiscard]] bool held() const { return held_; }

 private:
  std::uint64_t buttons_;
  bool held_ = false;
  glm::dvec3 offset_m_{0.0};  ///< added to the handle's position
  glm::dvec3 held_at_m_{0.0};
};

}  // namespace bisturi::runtime
