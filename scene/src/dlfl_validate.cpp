// validate(): every check reads the raw records directly and never trusts a link before checking
// it, so a broken structure is reported, not followed into a crash or an endless walk.

#include "bisturi/scene/dlfl_validate.h"

#include <algorithm>
#include <sstream>

namespace bisturi {

std::string ValidationReport::summary() const {
  std::string s;
  for (const auto& p : problems) {
    s += p;
    s += '\n';
  }
  return s;
}

namespace {

class Validator {
 public:
  Validator(const Dlfl& mesh, std::size_t max_problems) : m_(mesh), max_(max_problems) {}

  ValidationReport run() {
    check_free_lists();
    check_corners();
    check_faces();
    check_rotations();
    check_edges();
    check_labels();
    return std::move(report_);
  }

 private:
  template <class... Parts>
  void problem(const Parts&... parts) {
    if (report_.problems.size() >= max_) return;
    std::ostringstream out;
    (out << ... << parts);
    report_.problems.push_back(out.str());
    if (report_.problems.size() == max_)
      report_.problems.emplace_back("(further problems omitted)");
  }

  template <class Tag, class IsLive>
  void check_free_list(const char* what, std::size_t capacity, IsLive is_live) {
    const auto& list = m_.free_list(Tag{});
    std::vector<char> seen(capacity, 0);
    for (std::uint32_t i : list) {
      if (i >= capacity) {
        problem("free ", what, " list holds ", i, ", beyond the array of ", capacity);
      } else if (is_live(i)) {
        problem("free ", what, " list holds live ", to_string(Handle<Tag>(i)));
      } else if (seen[i]++) {
        problem("free ", what, " list holds ", to_string(Handle<Tag>(i)), " twice");
      }
    }
    std::size_t dead = 0;
    for (std::size_t i = 0; i < capacity; ++i)
      dead += is_live(i) ? 0 : 1;
    if (dead != list.size()) {
      problem(dead, " deleted ", what, " slots but ", list.size(), " in the free list");
    }
  }

  void check_free_lists() {
    check_free_list<VertexTag>("vertex", m_.vertex_capacity(), [&](std::size_t i) {
      return m_.alive(VertexId(static_cast<std::uint32_t>(i)));
    });
    check_free_list<CornerTag>("corner", m_.corner_capacity(), [&](std::size_t i) {
      return m_.alive(CornerId(static_cast<std::uint32_t>(i)));
    });
    check_free_list<FaceTag>("face", m_.face_capacity(), [&](std::size_t i) {
      return m_.alive(FaceId(static_cast<std::uint32_t>(i)));
    });
    check_free_list<EdgeTag>("edge", m_.edge_capacity(), [&](std::size_t i) {
      return m_.alive(EdgeId(static_cast<std::uint32_t>(i)));
    });
    check_free_list<RotationTag>("rotation", m_.rotation_capacity(), [&](std::size_t i) {
      return m_.alive(RotationId(static_cast<std::uint32_t>(i)));
    });
  }

  // A partner lookup that reports instead of throwing.
  CornerId partner(CornerId c) const {
    const EdgeId e = m_.corner_records()[c.idx].edge;
    if (!m_.alive(e)) return CornerId{};
    const auto& primary = m_.edge_records()[e.idx];
    if (primary.a == c) return primary.b;
    if (primary.b == c) return primary.a;
    const auto& lists = m_.extra_pair_lists();
    auto it =
        std::lower_bound(lists.begin(), lists.end(), e.idx,
                         [](const auto& entry, std::uint32_t key) { return entry.first < key; });
    if (it == lists.end() || it->first != e.idx) return CornerId{};
    for (const auto& p : it->second) {
      if (p.a == c) return p.b;
      if (p.b == c) return p.a;
    }
    return CornerId{};
  }

  void check_corners() {
    const auto& cs = m_.corner_records();
    for (std::uint32_t i = 0; i < cs.size(); ++i) {
      const CornerId c(i);
      if (!m_.alive(c)) continue;
      const auto& r = cs[i];
      if (!m_.alive(r.vertex)) problem(to_string(c), " names dead vertex ", to_string(r.vertex));
      if (!m_.alive(r.face)) problem(to_string(c), " names dead face ", to_string(r.face));
      if (!m_.alive(r.next) || !m_.alive(r.prev)) {
        problem(to_string(c), " links to a dead corner (next ", to_string(r.next), ", prev ",
                to_string(r.prev), ")");
        continue;
      }
      if (cs[r.next.idx].prev != c) {
        problem(to_string(c), ": next is ", to_string(r.next), " but its prev is ",
                to_string(cs[r.next.idx].prev));
      }
      if (cs[r.prev.idx].next != c) {
        problem(to_string(c), ": prev is ", to_string(r.prev), " but its next is ",
                to_string(cs[r.prev.idx].next));
      }
      if (cs[r.next.idx].face != r.face) {
        problem(to_string(c), " in ", to_string(r.face), " is followed by ", to_string(r.next),
                " in ", to_string(cs[r.next.idx].face));
      }
      const bool sphere = r.next == c;
      if (sphere && r.edge.valid()) {
        problem("point-sphere ", to_string(c), " names edge ", to_string(r.edge));
      }
      if (!sphere) {
        if (!m_.alive(r.edge)) {
          problem("side ", to_string(c), " -> ", to_string(r.next), " has no live edge (",
                  to_string(r.edge), ")");
        } else if (!partner(c).valid()) {
          problem(to_string(c), " is not a side of its edge ", to_string(r.edge));
        }
      }
    }
  }

  void check_faces() {
    const auto& cs = m_.corner_records();
    const auto& fs = m_.face_records();
    std::vector<char> on_cycle(cs.size(), 0);
    std::size_t counted = 0;
    for (std::uint32_t i = 0; i < fs.size(); ++i) {
      const FaceId f(i);
      if (!m_.alive(f)) continue;
      const CornerId first = fs[i].first;
      if (!m_.alive(first)) {
        problem(to_string(f), " starts at dead corner ", to_string(first));
        continue;
      }
      if (cs[first.idx].face != f) {
        problem(to_string(f), " starts at ", to_string(first), ", which names ",
                to_string(cs[first.idx].face));
        continue;
      }
      CornerId c = first;
      std::size_t steps = 0;
      do {
        if (on_cycle[c.idx]++) {
          problem(to_string(c), " lies on two face cycles (seen again from ", to_string(f), ")");
          break;
        }
        ++counted;
        c = cs[c.idx].next;
        if (!m_.alive(c) || ++steps > cs.size()) {
          problem("the cycle of ", to_string(f), " does not close");
          break;
        }
      } while (c != first);
    }
    if (counted != m_.num_corners()) {
      for (std::uint32_t i = 0; i < cs.size(); ++i) {
        if (m_.alive(CornerId(i)) && !on_cycle[i]) {
          problem(to_string(CornerId(i)), " is on no face cycle (it names ", to_string(cs[i].face),
                  ")");
        }
      }
    }
  }

  void check_rotations() {
    const auto& cs = m_.corner_records();
    const auto& rs = m_.rotation_records();
    const auto& vs = m_.vertex_records();
    rotation_of_.assign(cs.size(), kInvalidIndex);
    std::vector<char> listed(rs.size(), 0);
    for (std::uint32_t i = 0; i < vs.size(); ++i) {
      const VertexId v(i);
      if (!m_.alive(v)) continue;
      std::size_t rotations = 0;
      for (RotationId r = vs[i].first; r.valid(); r = m_.next_rotation(r)) {
        if (!m_.alive(r)) {
          problem(to_string(v), " lists dead rotation ", to_string(r));
          break;
        }
        if (listed[r.idx]++ || ++rotations > rs.size()) {
          problem("rotation list of ", to_string(v), " repeats ", to_string(r));
          break;
        }
        const CornerId start = rs[r.idx].corner;
        if (cs[start.idx].vertex != v) {
          problem(to_string(r), " of ", to_string(v), " starts at ", to_string(start), " of ",
                  to_string(cs[start.idx].vertex));
          continue;
        }
        CornerId c = start;
        std::size_t steps = 0;
        do {
          if (cs[c.idx].vertex != v) {
            problem(to_string(r), " of ", to_string(v), " reaches ", to_string(c), " of ",
                    to_string(cs[c.idx].vertex));
            break;
          }
          if (rotation_of_[c.idx] != kInvalidIndex) {
            problem(to_string(c), " is in two rotations (", to_string(r), " and ",
                    to_string(RotationId(rotation_of_[c.idx])), ")");
            break;
          }
          rotation_of_[c.idx] = r.idx;
          const CornerId entering = cs[c.idx].prev;
          c = entering == c ? c : partner(entering);
          if (!c.valid() || ++steps > cs.size()) {
            problem("the corners of ", to_string(r), " (", to_string(v), ") do not close");
            break;
          }
        } while (c != start);
      }
    }
    const auto& links = m_.rotation_links();
    for (std::size_t k = 0; k < links.size(); ++k) {
      if (k > 0 && links[k - 1].first >= links[k].first) problem("rotation links are not sorted");
      if (!m_.alive(RotationId(links[k].first)) || !m_.alive(RotationId(links[k].second))) {
        problem("rotation link ", to_string(RotationId(links[k].first)), " -> ",
                to_string(RotationId(links[k].second)), " names a dead rotation");
      }
    }
    for (std::uint32_t i = 0; i < rs.size(); ++i) {
      if (m_.alive(RotationId(i)) && !listed[i]) {
        problem(to_string(RotationId(i)), " is in no vertex's rotation list");
      }
    }
    for (std::uint32_t i = 0; i < cs.size(); ++i) {
      if (m_.alive(CornerId(i)) && rotation_of_[i] == kInvalidIndex) {
        problem(to_string(CornerId(i)), " is in no rotation of ", to_string(cs[i].vertex));
      }
    }
  }

  void check_pair(EdgeId e, const CornerPair& p, std::vector<char>& used) {
    const auto& cs = m_.corner_records();
    if (!m_.alive(p.a) || !m_.alive(p.b)) {
      problem(to_string(e), " holds a dead corner (", to_string(p.a), ", ", to_string(p.b), ")");
      return;
    }
    for (CornerId c : {p.a, p.b}) {
      if (cs[c.idx].edge != e) {
        problem(to_string(e), " holds ", to_string(c), ", which names ", to_string(cs[c.idx].edge));
      }
      if (used[c.idx]++) problem(to_string(c), " is a side of two pairs");
    }
    const CornerId na = cs[p.a.idx].next;
    const CornerId nb = cs[p.b.idx].next;
    if (cs[na.idx].vertex != cs[p.b.idx].vertex || cs[nb.idx].vertex != cs[p.a.idx].vertex) {
      problem(to_string(e), ": sides ", to_string(p.a), " and ", to_string(p.b),
              " are not opposite (", to_string(cs[p.a.idx].vertex), "->",
              to_string(cs[na.idx].vertex), " vs ", to_string(cs[p.b.idx].vertex), "->",
              to_string(cs[nb.idx].vertex), ")");
    }
  }

  void check_edges() {
    const auto& cs = m_.corner_records();
    const auto& es = m_.edge_records();
    std::vector<char> used(cs.size(), 0);
    for (std::uint32_t i = 0; i < es.size(); ++i) {
      if (m_.alive(EdgeId(i))) check_pair(EdgeId(i), es[i], used);
    }
    std::uint32_t previous_key = 0;
    bool first = true;
    for (const auto& [key, pairs] : m_.extra_pair_lists()) {
      const EdgeId e(key);
      if (!first && key <= previous_key)
        problem("extra pair lists are not sorted at ", to_string(e));
      first = false;
      previous_key = key;
      if (!m_.alive(e)) {
        problem("dead ", to_string(e), " has extra pairs");
        continue;
      }
      if (pairs.empty()) problem(to_string(e), " has an empty extra pair list");
      const CornerPair primary = es[key];
      const VertexId v1 = cs[primary.a.idx].vertex;
      const VertexId v2 = cs[primary.b.idx].vertex;
      std::vector<std::pair<std::uint32_t, std::uint32_t>> rotations{
          {rotation_of_[primary.a.idx], rotation_of_[primary.b.idx]}};
      for (const auto& p : pairs) {
        check_pair(e, p, used);
        if (!m_.alive(p.a) || !m_.alive(p.b)) continue;
        // Normalise the pair so that its first corner is on v1.
        const CornerId at1 = cs[p.a.idx].vertex == v1 ? p.a : p.b;
        const CornerId at2 = at1 == p.a ? p.b : p.a;
        if (cs[at1.idx].vertex != v1 || cs[at2.idx].vertex != v2) {
          problem(to_string(e), " joins ", to_string(v1), "-", to_string(v2),
                  " but one of its pairs joins ", to_string(cs[p.a.idx].vertex), "-",
                  to_string(cs[p.b.idx].vertex));
          continue;
        }
        const std::pair<std::uint32_t, std::uint32_t> rot{rotation_of_[at1.idx],
                                                          rotation_of_[at2.idx]};
        if (std::find(rotations.begin(), rotations.end(), rot) != rotations.end()) {
          problem(to_string(e), " holds two pairs in the same rotations");
        }
        rotations.push_back(rot);
      }
    }
  }

  void check_labels() {
    const auto& labels = m_.bounding_labels();
    if (labels.size() != m_.face_capacity()) {
      problem("label array has ", labels.size(), " entries for ", m_.face_capacity(), " faces");
      return;
    }
    for (std::uint32_t i = 0; i < labels.size(); ++i) {
      if (labels[i] > 1) problem(to_string(FaceId(i)), " has label value ", int(labels[i]));
      if (labels[i] != 0 && !m_.alive(FaceId(i))) {
        problem("deleted ", to_string(FaceId(i)), " still carries a boundary label");
      }
    }
    if (m_.positions().size() != m_.vertex_capacity()) {
      problem("position array has ", m_.positions().size(), " entries for ", m_.vertex_capacity(),
              " vertices");
    }
  }

  const Dlfl& m_;
  std::size_t max_;
  ValidationReport report_;
  std::vector<std::uint32_t> rotation_of_;
};

}  // namespace

ValidationReport validate(const Dlfl& mesh, std::size_t max_problems) {
  return Validator(mesh, max_problems).run();
}

}  // namespace bisturi
