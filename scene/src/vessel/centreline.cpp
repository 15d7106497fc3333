#include "bisturi/scene/vessel/centreline.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <functional>
#include <limits>
#include <numeric>
#include <queue>
#include <utility>

#include <glm/geometric.hpp>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/vessel/distance_field.h"

namespace bisturi {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

/// The mask's voxels as a graph: the bounding box of the nonzero voxels (one layer larger where
/// the volume allows), its inside voxels numbered compactly, 26-neighbour steps in mm.
struct VoxelGraph {
  std::array<std::int64_t, 3> lo{}, dims{};
  VolumeGeometry geometry;        // of the box
  std::vector<std::int32_t> id;   // box linear index -> node, or -1
  std::vector<std::int64_t> box;  // node -> box linear index
  std::vector<float> depth;       // node -> distance field (mm)
  struct Step {
    std::array<int, 3> d;
    std::int64_t offset;
    double length;
  };
  std::vector<Step> steps;

  [[nodiscard]] std::array<std::int64_t, 3> coords(std::int32_t node) const {
    const std::int64_t l = box[static_cast<std::size_t>(node)];
    return {l % dims[0], (l / dims[0]) % dims[1], l / (dims[0] * dims[1])};
  }
  [[nodiscard]] glm::dvec3 world(std::int32_t node) const {
    const auto c = coords(node);
    return geometry.index_to_world(glm::dvec3(c[0], c[1], c[2]));
  }
  [[nodiscard]] std::size_t size() const { return box.size(); }

  template <class F>
  void for_neighbours(std::int32_t node, F&& f) const {
    const auto c = coords(node);
    const std::int64_t l = box[static_cast<std::size_t>(node)];
    for (const Step& s : steps) {
      const std::int64_t x = c[0] + s.d[0], y = c[1] + s.d[1], z = c[2] + s.d[2];
      if (x < 0 || y < 0 || z < 0 || x >= dims[0] || y >= dims[1] || z >= dims[2]) continue;
      const std::int32_t m = id[static_cast<std::size_t>(l + s.offset)];
      if (m >= 0) f(m, s.length);
    }
  }
};

VoxelGraph build_graph(const Grid<std::uint8_t>& mask) {
  const VolumeGeometry& g = mask.geometry;
  if (mask.values.size() != g.voxel_count()) {
    throw InputError("centreline: the mask's values do not match its dims");
  }
  std::array<std::int64_t, 3> lo{g.dims[0], g.dims[1], g.dims[2]}, hi{-1, -1, -1};
  std::size_t n = 0;
  for (std::int64_t k = 0; k < g.dims[2]; ++k)
    for (std::int64_t j = 0; j < g.dims[1]; ++j)
      for (std::int64_t i = 0; i < g.dims[0]; ++i, ++n) {
        if (mask.values[n] == 0) continue;
        const std::int64_t c[3] = {i, j, k};
        for (int a = 0; a < 3; ++a) {
          lo[static_cast<std::size_t>(a)] = std::min(lo[static_cast<std::size_t>(a)], c[a]);
          hi[static_cast<std::size_t>(a)] = std::max(hi[static_cast<std::size_t>(a)], c[a]);
        }
      }
  if (hi[0] < 0) throw InputError("centreline: the mask is empty (no voxel inside)");
  VoxelGraph graph;
  for (std::size_t a = 0; a < 3; ++a) {
    lo[a] = std::max<std::int64_t>(0, lo[a] - 1);
    hi[a] = std::min<std::int64_t>(g.dims[a] - 1, hi[a] + 1);
    graph.dims[a] = hi[a] - lo[a] + 1;
  }
  graph.lo = lo;
  graph.geometry = g;
  graph.geometry.dims = graph.dims;
  graph.geometry.origin = g.index_to_world(glm::dvec3(lo[0], lo[1], lo[2]));

  Grid<std::uint8_t> crop;
  crop.geometry = graph.geometry;
  crop.values.resize(crop.geometry.voxel_count());
  graph.id.assign(crop.values.size(), -1);
  std::size_t b = 0;
  for (std::int64_t k = 0; k < graph.dims[2]; ++k)
    for (std::int64_t j = 0; j < graph.dims[1]; ++j)
      for (std::int64_t i = 0; i < graph.dims[0]; ++i, ++b) {
        crop.values[b] = mask.at(i + lo[0], j + lo[1], k + lo[2]) != 0 ? 1 : 0;
        if (crop.values[b] != 0) {
          graph.id[b] = static_cast<std::int32_t>(graph.box.size());
          graph.box.push_back(static_cast<std::int64_t>(b));
        }
      }
  if (graph.box.size() >= static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())) {
    throw InputError("centreline: the object has too many voxels");
  }
  const Grid<float> depth = distance_to_outside(crop);
  graph.depth.resize(graph.box.size());
  for (std::size_t v = 0; v < graph.box.size(); ++v) {
    const float d = depth.values[static_cast<std::size_t>(graph.box[v])];
    // No outside voxel at all (a mask filling the volume): the box's half-size bounds the depth.
    graph.depth[v] =
        std::isfinite(d)
            ? d
            : static_cast<float>(
                  glm::length(glm::dvec3(graph.dims[0], graph.dims[1], graph.dims[2]) * g.spacing));
  }
  for (int dz = -1; dz <= 1; ++dz)
    for (int dy = -1; dy <= 1; ++dy)
      for (int dx = -1; dx <= 1; ++dx) {
        if (dx == 0 && dy == 0 && dz == 0) continue;
        graph.steps.push_back({{dx, dy, dz},
                               dx + graph.dims[0] * (dy + graph.dims[1] * dz),
                               glm::length(glm::dvec3(dx, dy, dz) * g.spacing)});
      }
  return graph;
}

/// Shortest paths from `root`; a step costs its length times the mean of its ends' weights
/// (all 1 when `weight` is empty).
void shortest_paths(const VoxelGraph& g, std::int32_t root, const std::vector<double>& weight,
                    std::vector<double>& dist, std::vector<std::int32_t>& parent) {
  dist.assign(g.size(), kInf);
  parent.assign(g.size(), -1);
  using Item = std::pair<double, std::int32_t>;
  std::priority_queue<Item, std::vector<Item>, std::greater<>> queue;
  dist[static_cast<std::size_t>(root)] = 0.0;
  queue.push({0.0, root});
  while (!queue.empty()) {
    const auto [d, u] = queue.top();
    queue.pop();
    if (d > dist[static_cast<std::size_t>(u)]) continue;
    const double wu = weight.empty() ? 1.0 : weight[static_cast<std::size_t>(u)];
    g.for_neighbours(u, [&](std::int32_t v, double length) {
      const double wv = weight.empty() ? 1.0 : weight[static_cast<std::size_t>(v)];
      const double nd = d + length * 0.5 * (wu + wv);
      if (nd < dist[static_cast<std::size_t>(v)]) {
        dist[static_cast<std::size_t>(v)] = nd;
        parent[static_cast<std::size_t>(v)] = u;
        queue.push({nd, v});
      }
    });
  }
}

std::int32_t farthest(const std::vector<double>& dist) {
  std::int32_t best = -1;
  for (std::size_t v = 0; v < dist.size(); ++v) {
    if (std::isfinite(dist[v]) && (best < 0 || dist[v] > dist[static_cast<std::size_t>(best)]))
      best = static_cast<std::int32_t>(v);
  }
  return best;
}

/// The skeleton traced from one root: its voxels (a subtree of `parent`) and their children.
struct Skeleton {
  std::int32_t root = -1;
  std::vector<std::int32_t> parent;
  std::vector<std::vector<std::int32_t>> children;  // per node (empty off the skeleton)
  std::vector<char> on;
  std::size_t reached = 0;
  std::size_t pruned = 0;
};

Skeleton trace_skeleton(const VoxelGraph& g, std::int32_t root, const std::vector<double>& weight,
                        const CentrelineOptions& options) {
  Skeleton s;
  s.root = root;
  std::vector<double> plain, weighted;
  std::vector<std::int32_t> unused;
  shortest_paths(g, root, {}, plain, unused);
  shortest_paths(g, root, weight, weighted, s.parent);

  const double hmax = std::max({g.geometry.spacing.x, g.geometry.spacing.y, g.geometry.spacing.z});
  std::vector<char> covered(g.size(), 0);
  std::vector<std::int32_t> order;
  for (std::size_t v = 0; v < g.size(); ++v) {
    if (std::isfinite(plain[v])) {
      order.push_back(static_cast<std::int32_t>(v));
    } else {
      covered[v] = 1;
    }
  }
  s.reached = order.size();
  std::sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
    const double da = plain[static_cast<std::size_t>(a)], db = plain[static_cast<std::size_t>(b)];
    return da != db ? da > db : a < b;
  });
  s.on.assign(g.size(), 0);
  s.children.assign(g.size(), {});
  s.on[static_cast<std::size_t>(root)] = 1;
  covered[static_cast<std::size_t>(root)] = 1;

  const auto cover_ball = [&](std::int32_t node) {
    const double radius =
        options.ball_scale * g.depth[static_cast<std::size_t>(node)] + options.ball_voxels * hmax;
    const auto c = g.coords(node);
    std::array<std::int64_t, 3> r{};
    for (int a = 0; a < 3; ++a) {
      r[static_cast<std::size_t>(a)] =
          static_cast<std::int64_t>(std::floor(radius / g.geometry.spacing[a]));
    }
    for (std::int64_t z = std::max<std::int64_t>(0, c[2] - r[2]);
         z <= std::min(g.dims[2] - 1, c[2] + r[2]); ++z)
      for (std::int64_t y = std::max<std::int64_t>(0, c[1] - r[1]);
           y <= std::min(g.dims[1] - 1, c[1] + r[1]); ++y)
        for (std::int64_t x = std::max<std::int64_t>(0, c[0] - r[0]);
             x <= std::min(g.dims[0] - 1, c[0] + r[0]); ++x) {
          const std::int32_t m =
              g.id[static_cast<std::size_t>(x + g.dims[0] * (y + g.dims[1] * z))];
          if (m < 0 || covered[static_cast<std::size_t>(m)]) continue;
          const glm::dvec3 d = glm::dvec3(x - c[0], y - c[1], z - c[2]) * g.geometry.spacing;
          if (glm::dot(d, d) <= radius * radius) covered[static_cast<std::size_t>(m)] = 1;
        }
  };

  std::size_t next = 0;
  std::vector<std::int32_t> path;
  while (true) {
    while (next < order.size() && covered[static_cast<std::size_t>(order[next])])
      ++next;
    if (next == order.size()) break;
    const std::int32_t tip = order[next];
    path.clear();
    std::int32_t v = tip;
    double length = 0.0;
    while (!s.on[static_cast<std::size_t>(v)]) {
      path.push_back(v);
      const std::int32_t p = s.parent[static_cast<std::size_t>(v)];
      length += glm::distance(g.world(v), g.world(p));
      v = p;
    }
    const std::int32_t join = v;
    const double min_length = options.min_branch_mm > 0.0
                                  ? options.min_branch_mm
                                  : options.prune_radii * g.depth[static_cast<std::size_t>(join)];
    const bool keep = join == root || length >= min_length;
    for (const std::int32_t p : path) {
      covered[static_cast<std::size_t>(p)] = 1;
      cover_ball(p);
    }
    if (!keep) {
      ++s.pruned;
      continue;
    }
    for (const std::int32_t p : path) {
      s.on[static_cast<std::size_t>(p)] = 1;
      s.children[static_cast<std::size_t>(s.parent[static_cast<std::size_t>(p)])].push_back(p);
    }
  }
  for (auto& c : s.children)
    std::sort(c.begin(), c.end());
  return s;
}

struct VoxelBranch {
  int parent = -1;
  std::vector<std::int32_t> nodes;
  bool ends_at_tip = true;
};

/// The runs of the skeleton between the root, bifurcations and tips; parents first.
std::vector<VoxelBranch> branches_of(const Skeleton& s) {
  std::vector<VoxelBranch> out;
  struct Start {
    std::int32_t from, first;
    int parent;
  };
  std::vector<Start> pending;
  for (const std::int32_t c : s.children[static_cast<std::size_t>(s.root)])
    pending.push_back({s.root, c, -1});
  for (std::size_t i = 0; i < pending.size(); ++i) {
    const Start st = pending[i];
    VoxelBranch b;
    b.parent = st.parent;
    b.nodes = {st.from, st.first};
    std::int32_t v = st.first;
    while (s.children[static_cast<std::size_t>(v)].size() == 1) {
      v = s.children[static_cast<std::size_t>(v)][0];
      b.nodes.push_back(v);
    }
    const auto& kids = s.children[static_cast<std::size_t>(v)];
    b.ends_at_tip = kids.empty();
    const int id = static_cast<int>(out.size());
    out.push_back(std::move(b));
    for (const std::int32_t c : kids)
      pending.push_back({v, c, id});
  }
  return out;
}

/// Gaussian over arc length; the window is symmetric and shrinks near the ends (ends stay put).
std::vector<glm::dvec3> smooth_path(const std::vector<glm::dvec3>& p, double sigma) {
  std::vector<double> s(p.size(), 0.0);
  for (std::size_t i = 1; i < p.size(); ++i)
    s[i] = s[i - 1] + glm::distance(p[i - 1], p[i]);
  std::vector<glm::dvec3> out(p.size());
  for (std::size_t i = 0; i < p.size(); ++i) {
    const double w = std::min({3.0 * sigma, s[i] - s.front(), s.back() - s[i]});
    glm::dvec3 sum(0.0);
    double total = 0.0;
    for (std::size_t j = 0; j < p.size(); ++j) {
      const double ds = s[j] - s[i];
      if (std::abs(ds) > w + 1e-12) continue;
      const double weight = std::exp(-0.5 * ds * ds / (sigma * sigma));
      sum += weight * p[j];
      total += weight;
    }
    out[i] = sum / total;
  }
  return out;
}

}  // namespace

Centreline extract_centreline(const Grid<std::uint8_t>& mask, const CentrelineOptions& options) {
  const VoxelGraph g = build_graph(mask);
  double max_depth = 0.0;
  std::int32_t deepest = 0;
  for (std::size_t v = 0; v < g.size(); ++v) {
    if (g.depth[v] > max_depth) {
      max_depth = g.depth[v];
      deepest = static_cast<std::int32_t>(v);
    }
  }
  // Sato's penalty, with the power 4 instead of 16: steep enough within the inner half of the
  // radius that paths round a bend keep to the middle instead of cutting the corner.
  std::vector<double> weight(g.size());
  for (std::size_t v = 0; v < g.size(); ++v)
    weight[v] = 1.0 + 5000.0 * std::pow(1.0 - g.depth[v] / max_depth, 4.0);

  std::vector<double> dist;
  std::vector<std::int32_t> unused;
  shortest_paths(g, deepest, {}, dist, unused);
  std::int32_t root = farthest(dist);
  Skeleton skeleton = trace_skeleton(g, root, weight, options);
  std::vector<VoxelBranch> branches = branches_of(skeleton);

  // The start: one of the ends (the root or a tip).
  std::vector<std::int32_t> ends = {root};
  std::vector<double> end_width = {0.0};
  for (const VoxelBranch& b : branches) {
    if (!b.ends_at_tip) continue;
    ends.push_back(b.nodes.back());
    end_width.push_back(0.0);
  }
  // An end's width: the largest radius on its terminal branch within half the branch's length
  // and four of its radii from the end (a trunk is wider than its daughters, a taper's wide end
  // than its narrow one).
  const auto width_near = [&](const VoxelBranch& b, bool from_back) {
    double widest = 0.0, length = 0.0;
    for (const std::int32_t n : b.nodes)
      widest = std::max(widest, static_cast<double>(g.depth[static_cast<std::size_t>(n)]));
    for (std::size_t k = 1; k < b.nodes.size(); ++k)
      length += glm::distance(g.world(b.nodes[k - 1]), g.world(b.nodes[k]));
    const double reach = std::min(0.5 * length, 4.0 * widest);
    double w = 0.0, s = 0.0;
    for (std::size_t k = 0; k < b.nodes.size() && s <= reach; ++k) {
      const std::size_t i = from_back ? b.nodes.size() - 1 - k : k;
      w = std::max(w, static_cast<double>(g.depth[static_cast<std::size_t>(b.nodes[i])]));
      if (k + 1 < b.nodes.size()) {
        const std::size_t j = from_back ? i - 1 : i + 1;
        s += glm::distance(g.world(b.nodes[i]), g.world(b.nodes[j]));
      }
    }
    return w;
  };
  for (std::size_t e = 0; e < ends.size(); ++e) {
    for (const VoxelBranch& b : branches) {
      if (e == 0 && b.parent == -1 && b.nodes.front() == root) {
        end_width[e] = std::max(end_width[e], width_near(b, false));
      } else if (e > 0 && b.ends_at_tip && b.nodes.back() == ends[e]) {
        end_width[e] = std::max(end_width[e], width_near(b, true));
      }
    }
  }
  std::size_t chosen = 0;
  for (std::size_t e = 1; e < ends.size(); ++e) {
    if (options.start_mm) {
      if (glm::distance(g.world(ends[e]), *options.start_mm) <
          glm::distance(g.world(ends[chosen]), *options.start_mm))
        chosen = e;
    } else if (end_width[e] > end_width[chosen] * (1.0 + 1e-9)) {
      chosen = e;
    }
  }
  if (ends[chosen] != root) {
    root = ends[chosen];
    skeleton = trace_skeleton(g, root, weight, options);
    branches = branches_of(skeleton);
  }

  const double hmax = std::max({g.geometry.spacing.x, g.geometry.spacing.y, g.geometry.spacing.z});
  const double sigma = options.smoothing_mm > 0.0 ? options.smoothing_mm : 2.0 * hmax;
  Centreline out;
  out.mask_voxels = skeleton.reached;
  out.pruned_branches = skeleton.pruned;
  out.max_radius_mm = max_depth;
  for (std::size_t i = 0; i < branches.size(); ++i) {
    const VoxelBranch& vb = branches[i];
    CentrelineBranch b;
    b.id = static_cast<int>(i);
    b.parent = vb.parent;
    b.ends_at_tip = vb.ends_at_tip;
    std::vector<glm::dvec3> raw;
    for (const std::int32_t n : vb.nodes) {
      raw.push_back(g.world(n));
      b.radius_mm.push_back(g.depth[static_cast<std::size_t>(n)]);
    }
    b.points = smooth_path(raw, sigma);
    double d =
        vb.parent < 0 ? 0.0 : out.branches[static_cast<std::size_t>(vb.parent)].distance_mm.back();
    b.distance_mm.push_back(d);
    for (std::size_t k = 1; k < b.points.size(); ++k) {
      d += glm::distance(b.points[k - 1], b.points[k]);
      b.distance_mm.push_back(d);
    }
    if (!vb.ends_at_tip) out.bifurcations.push_back(b.points.back());
    out.branches.push_back(std::move(b));
  }
  return out;
}

}  // namespace bisturi
