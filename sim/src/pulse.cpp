// The heartbeat's pressure on a vessel's wall (see pulse.h).

#include "bisturi/sim/pulse.h"

#include <cmath>

#include <glm/geometric.hpp>

namespace bisturi::sim {

double cardiac_waveform(double phase) {
  constexpr double kPeak = 0.15;   // systolic peak, fraction of the cycle
  constexpr double kDecay = 0.20;  // time constant of the decay after it
  const double p = phase - std::floor(phase);
  if (p < kPeak) {
    const double s = std::sin(0.5 * 3.141592653589793 * p / kPeak);
    return s * s;
  }
  // An exponential decay, less the straight line through its end value, so the cycle closes at 0.
  const double end = std::exp(-(1.0 - kPeak) / kDecay);
  const double decay = std::exp(-(p - kPeak) / kDecay);
  return decay - end * (p - kPeak) / (1.0 - kPeak);
}

void apply_lumen_pressure(SoftBody& body, double pressure_Pa) {
  if (pressure_Pa == 0.0) return;
  const std::vector<std::uint32_t>& idx = body.triangles().indices;
  const std::vector<glm::dvec3>& x = body.positions();
  // The cross product is twice the area along the winding's normal; orientation() makes it point
  // out of the tissue; each of the three vertices takes a third.
  const double share = pressure_Pa * body.orientation() / 6.0;
  for (std::size_t t = 0; t + 2 < idx.size(); t += 3) {
    const glm::dvec3 n = glm::cross(x[idx[t + 1]] - x[idx[t]], x[idx[t + 2]] - x[idx[t]]);
    const glm::dvec3 f = share * n;
    for (int c = 0; c < 3; ++c) {
      const VertexId v(idx[t + c]);
      if (body.mass(v) > 0.0) body.add_force(v, f);
    }
  }
}

}  // namespace bisturi::sim
