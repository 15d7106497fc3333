#pragma once
// Exceptions thrown at the simulation layer's boundaries (scene/errors.h style). Numerical
// trouble inside a step is never thrown: it is rolled back and reported as a SimEvent.

#include <stdexcept>

namespace bisturi::sim {

/// Base of every error the sim layer throws.
class SimError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Bad parameters: a non-positive time step, a negative stiffness, a solid with no faces.
class SimInputError : public SimError {
 public:
  using SimError::SimError;
};

/// A cut that could not be applied (path off the surface, too short, along the boundary). The
/// solid is unchanged when this is thrown before surgery starts (every check comes first).
class CutError : public SimError {
 public:
  using SimError::SimError;
};

/// The collision library (Embree) failed: device creation or a build.
class CollisionError : public SimError {
 public:
  using SimError::SimError;
};

}  // namespace bisturi::sim
