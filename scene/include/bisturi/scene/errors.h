#pragma once
// Exceptions thrown at the scene layer's boundaries. Messages name the element (or file) and the
// reason; an operation that throws has left its data unchanged.

#include <stdexcept>
#include <string>

namespace bisturi {

/// Base of every error the scene layer reports.
class SceneError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// An operator was asked for something that would break the structure: a stale or foreign
/// handle, a vertex that still has edges, corners that cannot take an edge.
class TopologyError : public SceneError {
 public:
  using SceneError::SceneError;
};

/// Labelled (boundary) faces in opposite orientations were about to be joined (seed figure 39).
class LabelOrientationError : public TopologyError {
 public:
  using TopologyError::TopologyError;
};

/// Input data (polygon lists, coordinates) that cannot form the requested solid.
class InputError : public SceneError {
 public:
  using SceneError::SceneError;
};

}  // namespace bisturi
