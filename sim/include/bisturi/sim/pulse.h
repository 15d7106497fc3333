#pragma once
// The heartbeat in a vessel's wall: its lumen pressure follows a cardiac waveform at the heart
// rate, and the pressure above diastole pushes the wall out through the simulation (the wall is
// at rest at diastolic pressure), so it pulses, yields to instruments while it does, and a probe
// on it feels the beat.

#include "bisturi/sim/soft_body.h"

namespace bisturi::sim {

/// Millimetres of mercury in pascals.
inline constexpr double kPascalPerMmHg = 133.322;

/// The arterial pressure pulse as a fraction of the pulse pressure at `phase` (cycles; only its
/// fractional part counts): 0 at the end of diastole, a systolic upstroke to 1 at 0.15 of the
/// cycle, then a decay back to 0 at the cycle's end (continuous through it).
double cardiac_waveform(double phase);

/// Adds to each free vertex of `body` its share (a third) of the pressure force on each surface
/// triangle around it: pressure_Pa times the triangle's area along its outward normal. For the
/// next step only, like every external force.
void apply_lumen_pressure(SoftBody& body, double pressure_Pa);

}  // namespace bisturi::sim
