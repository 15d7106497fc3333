#pragma once
// Internal to sim/: every corner of a vertex, over all its rotations (a non-manifold vertex has
// one rotation per fan), for the passes that walk the faces around a vertex.

#include "bisturi/scene/dlfl.h"

namespace bisturi::sim {

template <class F>
void for_each_corner(const Dlfl& mesh, VertexId v, F&& f) {
  for (RotationId r = mesh.first_rotation(v); r.valid(); r = mesh.next_rotation(r)) {
    const CornerId start = mesh.rotation_corner(r);
    CornerId c = start;
    do {
      f(c);
      c = mesh.rot_next(c);
    } while (c != start);
  }
}

}  // namespace bisturi::sim
