// A glove's fingertips from the hand's pose and joints (see hand_model.h).

#include "hand_model.h"

#include <cmath>

namespace bisturi::runtime {

namespace {

struct FingerShape {
  double base_x;  ///< across the hand, as a share of the shaft
  double base_y;  ///< towards the palm
  double reach;   ///< straight length, as a share of the shaft
};
// Thumb to little finger: the thumb sits on the palm side and is the shortest but one.
constexpr std::array<FingerShape, kHandFingers> kFingers{{{-0.40, 0.25, 0.60},
                                                          {-0.20, 0.0, 0.80},
                                                          {0.0, 0.0, 0.85},
                                                          {0.20, 0.0, 0.80},
                                                          {0.38, 0.0, 0.65}}};
// Share of a finger's length in each of its segments (base to tip), for up to three joints.
constexpr std::array<double, 3> kSegments{0.45, 0.30, 0.25};

}  // namespace

std::array<glm::dvec3, kHandFingers> fingertips_mm(const glm::dvec3& tip_mm,
                                                    const glm::dquat& hand, double shaft_mm,
                                                    std::span<const double> joints_rad) {
  const std::size_t per_finger = joints_rad.size() / kHandFingers;
  std::array<glm::dvec3, kHandFingers> out{};
  for (std::size_t f = 0; f < kHandFingers; ++f) {
    const FingerShape& shape = kFingers[f];
    glm::dvec3 p(shape.base_x * shaft_mm, shape.base_y * shaft_mm, shaft_mm);  // hand frame
    double angle = 0.0;
    for (std::size_t s = 0; s < kSegments.size(); ++s) {
      if (s < per_finger) angle += joints_rad[f * per_finger + s];
      const double length = kSegments[s] * shape.reach * shaft_mm;
      p += length * glm::dvec3(0.0, std::sin(angle), -std::cos(angle));
    }
    out[f] = tip_mm + hand * p;
  }
  return out;
}

}  // namespace bisturi::runtime
