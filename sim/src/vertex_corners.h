#pragma once
// Internal to sim/: every corner of a vertex, over all its rotations (a non-manifold vertex has
// one rotation per fan), for the passes that walk the faces around a vertex.

#include "bisturi/scene/dlfl.h"

namespace bisturi::sim {

/// Whether any corner of v passes `test`, stopping at the first that does (without a list of
/// the corners: a cut's vertex grid asks this of every vertex of a 20k-vertex surface).
template <class Test>
bool any_corner(const Dlfl& mesh, VertexId v, Test&& test) {
  for (RotationId r = mesh.first_rotation(v); r.valid(); r = mesh.next_rotation(r)) {
    const CornerId start = mesh.rotation_corner(r);
    CornerId c = start;
    do {
      if (test(c)) return true;
      c = mesh.rot_next(c);
    } while (c != start);
  }
  return false;
}

template <class F>
void for_each_corner(const Dlfl& mesh, VertexId v, F&& f) {
  (void)any_corner(mesh, v, [&](CornerId c) {
    f(c);
    return false;
  });
}

}  // namespace bisturi::sim
