#pragma once
// Taubin lambda/mu smoothing of vertex positions: a shrinking Laplacian step (lambda > 0)
// followed by an inflating one (mu < -lambda), so noise goes while the mean size stays (a
// low-pass filter with pass-band frequency k_pb = 1/lambda + 1/mu, about 0.1 by default).
// Uniform (umbrella) weights over each vertex's neighbours in all its rotations. Topology is not
// touched.

#include <cstddef>
#include <functional>

#include "bisturi/scene/dlfl.h"

namespace bisturi::lod {

struct SmoothOptions {
  std::size_t iterations = 10;  ///< one iteration = one lambda step and one mu step
  double lambda = 0.5;
  double mu = -0.53;
  /// Vertices on a labelled (boundary) face stay where they are.
  bool fix_boundary = true;
  /// Non-manifold junction vertices (several rotations) stay where they are.
  bool fix_junctions = true;
  /// Called with (iterations done, iterations) after every iteration.
  std::function<void(std::size_t, std::size_t)> progress;
};

struct SmoothStats {
  std::size_t moved_vertices = 0;  ///< vertices that were free to move
  std::size_t fixed_vertices = 0;  ///< boundary or junction vertices held in place
};

/// Smooths the positions of `mesh` in place. Throws InputError for lambda <= 0 or mu >= -lambda.
SmoothStats smooth_taubin(Dlfl& mesh, const SmoothOptions& options = {});

}  // namespace bisturi::lod
