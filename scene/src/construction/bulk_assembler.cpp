// The fast path of construction: the final DLFL of a rotation system written in one pass, with
// exactly the structure insert_rotation_system() reaches one operator at a time (one corner per
// half-edge, one face per cycle, one rotation per fan, a non-manifold edge node for pairs of the
// same two vertices in different rotations, labelled hole faces). Linear time, no searches.

#include <algorithm>
#include <unordered_map>

#include "rotation_system.h"

namespace bisturi::construction {

class BulkAssembler {
 public:
  static std::vector<VertexId> run(Dlfl& d, const RotationSystem& rs,
                                   std::span<const Dlfl::Vec3> positions,
                                   const InsertOptions& options,
                                   ScratchVector<CornerId>* corner_of_half_edge) {
    const std::size_t nv = positions.size();
    const auto nh = static_cast<std::uint32_t>(rs.from.size());
    const std::size_t nfans = rs.fan_vertex.size();

    // Vertices: new ones are appended; joined ones keep their handle.
    std::vector<VertexId> vertices(nv);
    ScratchVector<std::uint32_t> fan_count(nv, 0);
    for (std::uint32_t vertex : rs.fan_vertex)
      ++fan_count[vertex];

    // Exact room for what is appended (one face per polygon and hole loop, one rotation per fan,
    // a point sphere per vertex without fans), so no array grows by doubling.
    {
      std::size_t lone = 0;
      for (std::size_t v = 0; v < nv; ++v) {
        const bool joined = !options.join_vertices.empty() && options.join_vertices[v].valid();
        lone += !joined && fan_count[v] == 0 ? 1 : 0;
      }
      std::size_t polygons = 0;
      for (std::uint32_t h = 0; h < rs.face_half_edges; ++h)
        polygons += rs.next[h] < h ? 1 : 0;
      const std::size_t faces = d.faces_.size() + lone + polygons + rs.hole_loops.size();
      d.vertices_.reserve(d.vertices_.size() + nv);
      d.positions_.reserve(d.positions_.size() + nv);
      d.corners_.reserve(d.corners_.size() + lone + nh);
      d.faces_.reserve(faces);
      d.bounding_.reserve(faces);
      d.rotations_.reserve(d.rotations_.size() + lone + nfans);
    }
    for (std::size_t v = 0; v < nv; ++v) {
      const VertexId join = options.join_vertices.empty() ? VertexId{} : options.join_vertices[v];
      if (join.valid()) {
        vertices[v] = join;
      } else if (fan_count[v] == 0) {
        vertices[v] = d.create_vertex(positions[v]);  // a lone point sphere
      } else {
        vertices[v] = VertexId(static_cast<std::uint32_t>(d.vertices_.size()));
        d.vertices_.push_back({RotationId{}});
        d.positions_.push_back(positions[v]);
      }
    }
    d.vertex_props_.resize(d.vertices_.size());

    // Corners: half-edge h becomes corner base + h.
    const auto base = static_cast<std::uint32_t>(d.corners_.size());
    auto corner = [base](std::uint32_t h) { return CornerId(base + h); };
    d.corners_.resize(base + static_cast<std::size_t>(nh));
    for (std::uint32_t h = 0; h < nh; ++h) {
      auto& c = d.corners_[base + h];
      c.vertex = vertices[rs.from[h]];
      c.next = corner(rs.next[h]);
      d.corners_[base + rs.next[h]].prev = corner(h);
    }
    d.corner_props_.resize(d.corners_.size());

    // Faces: one per next-cycle; hole loops are labelled.
    ScratchVector<char> is_hole_start(nh, 0);
    for (std::uint32_t k : rs.hole_loops)
      is_hole_start[k] = 1;
    for (std::uint32_t h = 0; h < nh; ++h) {
      if (d.corners_[base + h].face.valid()) continue;
      const FaceId f(static_cast<std::uint32_t>(d.faces_.size()));
      d.faces_.push_back({corner(h)});
      bool hole = false;
      std::uint32_t x = h;
      do {
        d.corners_[base + x].face = f;
        hole = hole || is_hole_start[x];
        x = rs.next[x];
      } while (x != h);
      d.bounding_.push_back(hole ? 1 : 0);
    }
    d.face_props_.resize(d.faces_.size());

    // Rotations: one per fan, anchored at the fan's first half-edge, listed in fan order.
    ScratchVector<std::uint32_t> fan_anchor(nfans, kNone);
    for (std::uint32_t h = 0; h < nh; ++h) {
      if (fan_anchor[rs.fan[h]] == kNone) fan_anchor[rs.fan[h]] = h;
    }
    ScratchVector<RotationId> rotation_of_fan(nfans);
    for (std::uint32_t f = 0; f < nfans; ++f) {
      const RotationId r(static_cast<std::uint32_t>(d.rotations_.size()));
      d.rotations_.push_back({corner(fan_anchor[f])});
      rotation_of_fan[f] = r;
      const VertexId v = vertices[rs.fan_vertex[f]];
      if (!d.vertices_[v.idx].first.valid()) {
        d.vertices_[v.idx].first = r;
      } else {
        d.set_next_rotation(d.last_rotation(v), r);
      }
    }

    // Edges: one per twin pair; pairs of the same two vertices in different rotations share an
    // edge node (only possible where a vertex has several fans, so only those are looked up).
    std::unordered_map<std::uint64_t, std::vector<EdgeId>> multi;
    auto key = [&](std::uint32_t h) {
      const std::uint64_t a = vertices[rs.from[h]].idx, b = vertices[rs.to[h]].idx;
      return a < b ? (a << 32) | b : (b << 32) | a;
    };
    auto rotation_pair = [&](CornerPair p) {
      // The rotations of a pair's two corners, ordered by vertex so that pairs compare alike.
      const auto& cs = d.corners_;
      const bool a_first = cs[p.a.idx].vertex.idx < cs[p.b.idx].vertex.idx;
      const std::uint32_t ra = rotation_of_fan[rs.fan[p.a.idx - base]].idx;
      const std::uint32_t rb = rotation_of_fan[rs.fan[p.b.idx - base]].idx;
      return a_first ? std::pair(ra, rb) : std::pair(rb, ra);
    };
    d.edges_.reserve(d.edges_.size() + nh / 2);
    for (std::uint32_t h = 0; h < nh; ++h) {
      const std::uint32_t t = rs.twin[h];
      if (t < h) continue;
      const CornerPair pair{corner(h), corner(t)};
      const bool junction =
          fan_count[rs.from[h]] > 1 || fan_count[rs.to[h]] > 1 ||
          (!options.join_vertices.empty() &&
           (options.join_vertices[rs.from[h]].valid() || options.join_vertices[rs.to[h]].valid()));
      EdgeId e;
      if (junction) {
        auto& candidates = multi[key(h)];
        const auto mine = rotation_pair(pair);
        for (EdgeId c : candidates) {
          bool distinct = true;
          for (const CornerPair& p : d.edge_pairs(c))
            distinct = distinct && rotation_pair(p) != mine;
          if (distinct) {
            e = c;
            break;
          }
        }
        if (e.valid()) {
          auto* extra = d.extra_pairs_of(e);
          if (extra == nullptr) {
            auto it = std::lower_bound(
                d.extra_pairs_.begin(), d.extra_pairs_.end(), e.idx,
                [](const auto& entry, std::uint32_t k) { return entry.first < k; });
            extra = &d.extra_pairs_.emplace(it, e.idx, std::vector<CornerPair>{})->second;
          }
          extra->push_back(pair);
        } else {
          e = EdgeId(static_cast<std::uint32_t>(d.edges_.size()));
          d.edges_.push_back(pair);
          candidates.push_back(e);
        }
      } else {
        e = EdgeId(static_cast<std::uint32_t>(d.edges_.size()));
        d.edges_.push_back(pair);
      }
      d.corners_[pair.a.idx].edge = e;
      d.corners_[pair.b.idx].edge = e;
    }
    d.edge_props_.resize(d.edges_.size());
    ++d.topology_version_;
    if (options.progress) options.progress(nh / 2, nh / 2);

    if (corner_of_half_edge != nullptr) {
      corner_of_half_edge->resize(nh);
      for (std::uint32_t h = 0; h < nh; ++h)
        (*corner_of_half_edge)[h] = corner(h);
    }
    return vertices;
  }
};

std::vector<VertexId> assemble_rotation_system(Dlfl& dlfl, const RotationSystem& rs,
                                               std::span<const Dlfl::Vec3> positions,
                                               const InsertOptions& options,
                                               ScratchVector<CornerId>* corner_of_half_edge) {
  return BulkAssembler::run(dlfl, rs, positions, options, corner_of_half_edge);
}

}  // namespace bisturi::construction
