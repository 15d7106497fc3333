// InsertEdge and DeleteEdge with the label rules of procedures 1 and 2 and the non-manifold edge
// lists of section 4.3. Corner surgery keeps every existing corner on the side it already
// started, so edge records never need rewriting; only the two new sides get corners.
// Each operator touches the corners of the faces it changes and, where a face is renamed, only
// the shorter cycle (found by walking both in lockstep).

#include <algorithm>
#include <cmath>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/errors.h"

namespace bisturi {

void Dlfl::assign_face(CornerId start, FaceId f) {
  CornerId c = start;
  do {
    corners_[c.idx].face = f;
    c = corners_[c.idx].next;
  } while (c != start);
}

std::pair<FaceId, FaceId> Dlfl::split_face(FaceId f, CornerId a, CornerId b) {
  const bool a_shorter = first_cycle_is_shorter(a, b);
  const CornerId short_start = a_shorter ? a : b;
  const FaceId fresh = new_face(short_start);
  assign_face(short_start, fresh);
  faces_[f.idx].first = a_shorter ? b : a;
  return a_shorter ? std::pair(fresh, f) : std::pair(f, fresh);
}

void Dlfl::absorb_face(FaceId kept, FaceId gone, CornerId from, CornerId until) {
  for (CornerId c = from; c != until; c = corners_[c.idx].next)
    corners_[c.idx].face = kept;
  faces_[kept.idx].first = until;
  free_face(gone);
}

bool Dlfl::first_cycle_is_shorter(CornerId a, CornerId b) const {
  CornerId x = a;
  CornerId y = b;
  while (true) {
    x = corners_[x.idx].next;
    if (x == a) return true;
    y = corners_[y.idx].next;
    if (y == b) return false;
  }
}

Dlfl::Vec3 Dlfl::newell_normal(FaceId f) const {
  Vec3 n(0.0);
  const CornerId start = faces_[f.idx].first;
  CornerId c = start;
  do {
    const Vec3& p = positions_[corners_[c.idx].vertex.idx];
    const Vec3& q = positions_[corners_[corners_[c.idx].next.idx].vertex.idx];
    n.x += (p.y - q.y) * (p.z + q.z);
    n.y += (p.z - q.z) * (p.x + q.x);
    n.z += (p.x - q.x) * (p.y + q.y);
    c = corners_[c.idx].next;
  } while (c != start);
  return n;
}

EdgeId Dlfl::find_edge_in_other_rotations(CornerId c1, CornerId c2) const {
  // Searched through the rotations of the two ends, never through the edge list (section 4.3).
  const VertexId v1 = corners_[c1.idx].vertex;
  const VertexId v2 = corners_[c2.idx].vertex;
  const bool several1 = next_rotation(vertices_[v1.idx].first).valid();
  const bool several2 = next_rotation(vertices_[v2.idx].first).valid();
  if (!several1 && !several2) return EdgeId{};
  const RotationId own1 = rotation_of(c1);
  const RotationId own2 = rotation_of(c2);
  // An edge that already has a pair in these same two rotations stays a separate (parallel)
  // edge: one edge node holds at most one pair per pair of rotations.
  auto has_pair_here = [&](EdgeId e) {
    for (const CornerPair& p : edge_pairs(e)) {
      const CornerId at1 = corners_[p.a.idx].vertex == v1 ? p.a : p.b;
      const CornerId at2 = at1 == p.a ? p.b : p.a;
      if (rotation_of(at1) == own1 && rotation_of(at2) == own2) return true;
    }
    return false;
  };
  auto search = [&](VertexId v, RotationId own, VertexId target) -> EdgeId {
    for (RotationId r = vertices_[v.idx].first; r.valid(); r = next_rotation(r)) {
      if (r == own) continue;
      const CornerId start = rotations_[r.idx].corner;
      CornerId c = start;
      do {
        if (!is_point_sphere(c) && corners_[corners_[c.idx].next.idx].vertex == target &&
            !has_pair_here(corners_[c.idx].edge)) {
          return corners_[c.idx].edge;
        }
        c = rot_next(c);
      } while (c != start);
    }
    return EdgeId{};
  };
  const EdgeId found = several1 ? search(v1, own1, v2) : EdgeId{};
  return found.valid() || !several2 ? found : search(v2, own2, v1);
}

InsertEdgeResult Dlfl::insert_edge(CornerId c1, CornerId c2, const InsertEdgeOptions& options) {
  require(c1, "insert_edge");
  require(c2, "insert_edge");
  if (c1 == c2) throw TopologyError("insert_edge: both ends are " + to_string(c1));
  const VertexId v1 = corners_[c1.idx].vertex;
  const VertexId v2 = corners_[c2.idx].vertex;
  if (v1 == v2) {
    throw TopologyError("insert_edge: " + to_string(c1) + " and " + to_string(c2) +
                        " are both on " + to_string(v1) + " (self-loop edges are not allowed)");
  }
  const FaceId f1 = corners_[c1.idx].face;
  const FaceId f2 = corners_[c2.idx].face;
  const bool split = (f1 == f2);
  if (!split && options.check_label_orientation && bounding_[f1.idx] && bounding_[f2.idx]) {
    const Vec3 n1 = newell_normal(f1);
    const Vec3 n2 = newell_normal(f2);
    const double d = n1.x * n2.x + n1.y * n2.y + n1.z * n2.z;
    const double l1 = std::sqrt(n1.x * n1.x + n1.y * n1.y + n1.z * n1.z);
    const double l2 = std::sqrt(n2.x * n2.x + n2.y * n2.y + n2.z * n2.z);
    if (l1 > 0.0 && l2 > 0.0 && d < -1e-9 * l1 * l2) {
      throw LabelOrientationError("insert_edge: labelled faces " + to_string(f1) + " and " +
                                  to_string(f2) +
                                  " have opposite orientations; joining them would make a "
                                  "boundary that does not follow the mesh (flip one label)");
    }
  }
  const EdgeId existing = find_edge_in_other_rotations(c1, c2);
  const bool ps1 = is_point_sphere(c1);
  const bool ps2 = is_point_sphere(c2);
  // Which of the two faces is renamed on a merge: the shorter one.
  const bool f1_shorter = !split && first_cycle_is_shorter(c1, c2);

  // ---- all checks done: from here on nothing throws except allocation ----
  const CornerId w1 = corners_[c1.idx].prev;
  const CornerId w2 = corners_[c2.idx].prev;
  const CornerId x1 = ps1 ? c1 : new_corner(v1);
  const CornerId x2 = ps2 ? c2 : new_corner(v2);
  auto link = [this](CornerId a, CornerId b) {
    corners_[a.idx].next = b;
    corners_[b.idx].prev = a;
  };
  if (!ps1 && !ps2) {
    link(w1, x1);
    link(x1, c2);
    link(w2, x2);
    link(x2, c1);
  } else if (ps1 && !ps2) {
    link(w2, x2);
    link(x2, c1);
    link(c1, c2);
  } else if (!ps1 && ps2) {
    link(w1, x1);
    link(x1, c2);
    link(c2, c1);
  } else {
    link(c1, c2);
    link(c2, c1);
  }

  EdgeId e = existing;
  if (e.valid()) {
    auto* extra = extra_pairs_of(e);
    if (extra == nullptr) {
      auto it =
          std::lower_bound(extra_pairs_.begin(), extra_pairs_.end(), e.idx,
                           [](const auto& entry, std::uint32_t key) { return entry.first < key; });
      extra = &extra_pairs_.emplace(it, e.idx, std::vector<CornerPair>{})->second;
    }
    extra->push_back({x1, x2});
  } else {
    e = new_edge({x1, x2});
  }
  corners_[x1.idx].edge = e;
  corners_[x2.idx].edge = e;

  InsertEdgeResult result;
  result.edge = e;
  result.side12 = x1;
  result.side21 = x2;
  result.split = split;
  result.joined_existing = existing.valid();

  if (split) {
    // Cycle through c2 is f1' (forward), cycle through c1 is f1'' (backward).
    corners_[x1.idx].face = f1;
    corners_[x2.idx].face = f1;
    const auto [forward, backward] = split_face(f1, c2, c1);
    const std::uint8_t label = bounding_[f1.idx];
    bounding_[forward.idx] = options.label_side == LabelSide::Forward ? label : 0;
    bounding_[backward.idx] = options.label_side == LabelSide::Backward ? label : 0;
    result.face_forward = forward;
    result.face_backward = backward;
  } else {
    const FaceId kept = f1_shorter ? f2 : f1;
    const FaceId gone = f1_shorter ? f1 : f2;
    bounding_[kept.idx] = (bounding_[f1.idx] || bounding_[f2.idx]) ? 1 : 0;
    // The renamed corners run from the absorbed face's corner up to the kept face's corner.
    absorb_face(kept, gone, f1_shorter ? c1 : c2, f1_shorter ? c2 : c1);
    corners_[x1.idx].face = kept;
    corners_[x2.idx].face = kept;
    result.face_forward = kept;
    result.face_backward = kept;
  }
  ++topology_version_;
  return result;
}

void Dlfl::remove_pair(EdgeId e, CornerId side) {
  auto* extra = extra_pairs_of(e);
  CornerPair& primary = edges_[e.idx];
  if (primary.a == side || primary.b == side) {
    if (extra == nullptr) {
      free_edge(e);
      return;
    }
    primary = extra->front();
    extra->erase(extra->begin());
  } else {
    extra->erase(std::find_if(extra->begin(), extra->end(),
                              [side](const CornerPair& p) { return p.a == side || p.b == side; }));
  }
  if (extra->empty()) {
    extra_pairs_.erase(std::find_if(extra_pairs_.begin(), extra_pairs_.end(),
                                    [e](const auto& entry) { return entry.first == e.idx; }));
  }
}

DeleteEdgeResult Dlfl::delete_pair(EdgeId e, CornerPair pair) {
  const CornerId a = pair.a;
  const CornerId b = pair.b;
  const bool dangling1 = corners_[a.idx].prev == b;  // v1 keeps no other edge in this rotation
  const bool dangling2 = corners_[b.idx].prev == a;
  const FaceId fa = corners_[a.idx].face;
  const FaceId fb = corners_[b.idx].face;
  const bool same = (fa == fb);
  const bool fa_shorter = !same && first_cycle_is_shorter(a, b);
  const CornerId na = corners_[a.idx].next;
  const CornerId nb = corners_[b.idx].next;
  const CornerId pa = corners_[a.idx].prev;
  const CornerId pb = corners_[b.idx].prev;
  auto link = [this](CornerId x, CornerId y) {
    corners_[x.idx].next = y;
    corners_[y.idx].prev = x;
  };
  auto make_point_sphere = [this](CornerId c) {
    corners_[c.idx].next = c;
    corners_[c.idx].prev = c;
    corners_[c.idx].edge = EdgeId{};
  };
  // Rotation anchors move off the corners that go away while the sides can still be followed.
  if (!dangling1) move_rotation_anchor(a, rot_next(a));
  if (!dangling2) move_rotation_anchor(b, rot_next(b));
  remove_pair(e, a);

  DeleteEdgeResult result;
  result.split = same;
  const std::uint8_t label = bounding_[fa.idx] || bounding_[fb.idx] ? 1 : 0;
  if (dangling1 || dangling2) {
    // The side pair is a spike: its free end turns back into a point sphere (the inverse of
    // joining a point sphere), the other end's corner goes away unless it dangles too.
    if (dangling1 && dangling2) {
      make_point_sphere(a);
      make_point_sphere(b);
      faces_[fa.idx].first = a;
      const FaceId fresh = new_face(b);
      corners_[b.idx].face = fresh;
      bounding_[fresh.idx] = label;
      result.face_a = fa;
      result.face_b = fresh;
    } else {
      const CornerId sphere = dangling1 ? a : b;
      const CornerId gone = dangling1 ? b : a;
      const CornerId before = dangling1 ? pb : pa;
      const CornerId after = dangling1 ? na : nb;
      link(before, after);
      free_corner(gone);
      make_point_sphere(sphere);
      faces_[fa.idx].first = after;
      const FaceId fresh = new_face(sphere);
      corners_[sphere.idx].face = fresh;
      bounding_[fresh.idx] = label;
      result.face_a = fa;
      result.face_b = fresh;
    }
    ++topology_version_;
    return result;
  }

  link(pa, nb);
  link(pb, na);
  free_corner(a);
  free_corner(b);
  if (same) {
    // f = delta v1 v2 gamma v2 v1 splits into (delta v1) through nb and (gamma v2) through na.
    const auto [through_nb, through_na] = split_face(fa, nb, na);
    bounding_[through_nb.idx] = label;
    bounding_[through_na.idx] = label;
    result.face_a = through_nb;
    result.face_b = through_na;
  } else {
    const FaceId kept = fa_shorter ? fb : fa;
    const FaceId gone = fa_shorter ? fa : fb;
    bounding_[kept.idx] = label;
    // After the splice the absorbed face's corners run from its first survivor to the kept one.
    absorb_face(kept, gone, fa_shorter ? na : nb, fa_shorter ? nb : na);
    result.face_a = kept;
    result.face_b = kept;
  }
  ++topology_version_;
  return result;
}

DeleteEdgeResult Dlfl::delete_edge_pair(CornerId side) {
  require(side, "delete_edge_pair");
  if (!corners_[side.idx].edge.valid()) {
    throw TopologyError("delete_edge_pair: " + to_string(side) + " is a point sphere (no edge)");
  }
  const EdgeId e = corners_[side.idx].edge;
  return delete_pair(e, pair_of(side));
}

DeleteEdgeResult Dlfl::delete_edge(EdgeId e) {
  require(e, "delete_edge");
  DeleteEdgeResult result;
  do {
    result = delete_pair(e, edges_[e.idx]);
  } while (alive(e));
  return result;
}

}  // namespace bisturi
