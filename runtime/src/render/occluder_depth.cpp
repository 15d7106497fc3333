#include "bisturi/runtime/render/occluder_depth.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <glm/geometric.hpp>
#include <glm/vec2.hpp>
#include <glm/vec4.hpp>

namespace bisturi::render {

namespace {

/// Cells are grown by this much (a share of a cell) in every test that claims coverage, and a
/// triangle thinner than it on screen is left out: the rasterizer's snapping and single
/// precision move edges by far less.
constexpr double kSlack = 0.02;
/// A box must lie this share of its distance behind the occluders' bound (depth precision).
constexpr double kDepthMargin = 1e-3;
/// Vertices nearer the eye's plane than this (clip w) make a surface no occluder in that eye.
constexpr double kNearest_w = 1e-3;
constexpr float kNone = std::numeric_limits<float>::infinity();

/// The cells [x0, x1] x [y0, y1] a screen rectangle (cell coordinates) touches, grown by the
/// slack and clamped to the grid; false when it misses the grid.
bool cell_span(double lo_x, double lo_y, double hi_x, double hi_y, std::uint32_t columns,
               std::uint32_t rows, int& x0, int& y0, int& x1, int& y1) {
  x0 = std::max(0, static_cast<int>(std::floor(lo_x - kSlack)));
  y0 = std::max(0, static_cast<int>(std::floor(lo_y - kSlack)));
  x1 = std::min(static_cast<int>(columns) - 1, static_cast<int>(std::floor(hi_x + kSlack)));
  y1 = std::min(static_cast<int>(rows) - 1, static_cast<int>(std::floor(hi_y + kSlack)));
  return x0 <= x1 && y0 <= y1;
}

/// Whether the segment a-b touches the cell (x, y) grown by the slack: the cells' axes are
/// covered by the caller's span, the segment's normal here (separating axes).
bool segment_touches(const glm::dvec2& a, const glm::dvec2& b, int x, int y) {
  const glm::dvec2 n(a.y - b.y, b.x - a.x);
  const double lo_x = x - kSlack, hi_x = x + 1 + kSlack;
  const double lo_y = y - kSlack, hi_y = y + 1 + kSlack;
  const double c = glm::dot(n, a);
  const double s0 = glm::dot(n, glm::dvec2(lo_x, lo_y)) - c;
  const double s1 = glm::dot(n, glm::dvec2(hi_x, lo_y)) - c;
  const double s2 = glm::dot(n, glm::dvec2(lo_x, hi_y)) - c;
  const double s3 = glm::dot(n, glm::dvec2(hi_x, hi_y)) - c;
  return std::min({s0, s1, s2, s3}) <= 0.0 && std::max({s0, s1, s2, s3}) >= 0.0;
}

}  // namespace

TriangleEdges triangle_edges(std::span<const std::uint32_t> indices, std::size_t vertex_count) {
  // Triangles round each vertex (compressed rows), then each edge found from its lower vertex.
  const std::size_t triangles = indices.size() / 3;
  std::vector<std::uint32_t> start(vertex_count + 1, 0);
  for (std::size_t k = 0; k < triangles * 3; ++k)
    if (indices[k] < vertex_count) ++start[indices[k] + 1];
  for (std::size_t v = 0; v < vertex_count; ++v)
    start[v + 1] += start[v];
  std::vector<std::uint32_t> round(start.back());
  std::vector<std::uint32_t> fill(start.begin(), start.end() - 1);
  for (std::size_t t = 0; t < triangles; ++t)
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t v = indices[t * 3 + static_cast<std::size_t>(c)];
      if (v < vertex_count) round[fill[v]++] = static_cast<std::uint32_t>(t);
    }

  TriangleEdges edges;
  edges.vertices.reserve(triangles * 3 / 2 + 1);
  edges.triangles.reserve(triangles * 3 / 2 + 1);
  const auto has = [&](std::size_t t, std::uint32_t v) {
    return indices[t * 3] == v || indices[t * 3 + 1] == v || indices[t * 3 + 2] == v;
  };
  for (std::size_t t = 0; t < triangles; ++t) {
    for (int c = 0; c < 3; ++c) {
      const std::uint32_t a = indices[t * 3 + static_cast<std::size_t>(c)];
      const std::uint32_t b = indices[t * 3 + static_cast<std::size_t>((c + 1) % 3)];
      if (a >= vertex_count || b >= vertex_count || a == b) continue;
      const std::uint32_t lo = std::min(a, b), hi = std::max(a, b);
      // The edge is listed by the first triangle round `lo` that holds it.
      std::int32_t first = -1, second = TriangleEdges::kBoundary;
      for (std::uint32_t k = start[lo]; k < start[lo + 1]; ++k) {
        const std::uint32_t other = round[k];
        if (!has(other, hi)) continue;
        if (first < 0) {
          first = static_cast<std::int32_t>(other);
        } else if (second == TriangleEdges::kBoundary) {
          second = static_cast<std::int32_t>(other);
        } else {
          second = TriangleEdges::kNonManifold;
        }
      }
      if (first != static_cast<std::int32_t>(t)) continue;
      edges.vertices.push_back({lo, hi});
      edges.triangles.push_back({first, second});
    }
  }
  return edges;
}

void OccluderDepth::begin(const std::array<glm::dmat4, 2>& view_projection,
                          const std::array<glm::dvec3, 2>& eye_mm, std::uint32_t columns,
                          std::uint32_t rows) {
  columns_ = columns;
  rows_ = rows;
  const std::size_t cells = std::size_t{columns} * rows;
  for (std::size_t e = 0; e < 2; ++e) {
    eyes_[e].view_projection = view_projection[e];
    eyes_[e].position_mm = eye_mm[e];
    eyes_[e].depth.assign(cells, kNone);
  }
  centred_.resize(cells);
  crossed_.resize(cells);
  farthest_.resize(cells);
}

void OccluderDepth::add(std::span<const float> vertices, std::size_t stride,
                        std::span<const std::uint32_t> indices, const TriangleEdges& edges,
                        bool two_sided) {
  if (columns_ == 0 || rows_ == 0 || stride < 3) return;
  for (Eye& eye : eyes_)
    add_to(eye, vertices, stride, indices, edges, two_sided);
}

void OccluderDepth::project(const Eye& eye, std::span<const float> vertices, std::size_t stride) {
  const std::size_t count = vertices.size() / stride;
  screen_.resize(count);
  for (std::size_t v = 0; v < count; ++v) {
    const float* p = &vertices[v * stride];
    const glm::dvec4 clip = eye.view_projection * glm::dvec4(p[0], p[1], p[2], 1.0);
    const double w = clip.w > kNearest_w ? clip.w : 0.0;  // 0: too near or behind
    const double x = w > 0.0 ? (clip.x / w + 1.0) * 0.5 * columns_ : 0.0;
    const double y = w > 0.0 ? (clip.y / w + 1.0) * 0.5 * rows_ : 0.0;
    screen_[v] = glm::dvec3(x, y, w);
  }
}

void OccluderDepth::add_to(Eye& eye, std::span<const float> vertices, std::size_t stride,
                           std::span<const std::uint32_t> indices, const TriangleEdges& edges,
                           bool two_sided) {
  project(eye, vertices, stride);
  const std::size_t count = screen_.size();
  const std::size_t triangles = indices.size() / 3;
  facing_.assign(triangles, 0);
  glm::dvec2 lo(std::numeric_limits<double>::infinity());
  glm::dvec2 hi(-std::numeric_limits<double>::infinity());
  for (std::size_t t = 0; t < triangles; ++t) {
    const std::uint32_t i0 = indices[t * 3], i1 = indices[t * 3 + 1], i2 = indices[t * 3 + 2];
    if (i0 >= count || i1 >= count || i2 >= count) return;  // not this surface's triangles
    // A surface reaching the eye's plane would need clipping: it hides nothing in this eye.
    if (screen_[i0].z == 0.0 || screen_[i1].z == 0.0 || screen_[i2].z == 0.0) return;
    const glm::dvec2 a(screen_[i0]), b(screen_[i1]), c(screen_[i2]);
    const double area2 = (b.x - a.x) * (c.y - a.y) - (b.y - a.y) * (c.x - a.x);
    // Thinner than the slack across its longest edge (area2 / longest): edge-on or degenerate.
    const double longest2 =
        std::max({glm::dot(b - a, b - a), glm::dot(c - b, c - b), glm::dot(a - c, a - c)});
    if (!(area2 * area2 > kSlack * kSlack * longest2)) continue;
    // Which side faces the eye, from the world positions (the screen's handedness aside).
    const float* p0 = &vertices[i0 * stride];
    const float* p1 = &vertices[i1 * stride];
    const float* p2 = &vertices[i2 * stride];
    const glm::dvec3 w0(p0[0], p0[1], p0[2]), w1(p1[0], p1[1], p1[2]), w2(p2[0], p2[1], p2[2]);
    const double towards = glm::dot(glm::cross(w1 - w0, w2 - w0), eye.position_mm - w0);
    const std::int8_t side = towards > 0.0 ? 1 : -1;
    if (!two_sided && side < 0) continue;  // culled by the rasterizer
    facing_[t] = side;
    lo = glm::min(lo, glm::min(a, glm::min(b, c)));
    hi = glm::max(hi, glm::max(b, glm::max(a, c)));
  }
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  if (!cell_span(lo.x, lo.y, hi.x, hi.y, columns_, rows_, x0, y0, x1, y1)) return;
  // This surface's scratch, over the cells its triangles span.
  const auto clear = [&](auto& per_cell, auto value) {
    for (int y = y0; y <= y1; ++y) {
      const auto row = per_cell.begin() + static_cast<std::ptrdiff_t>(y) * columns_;
      std::fill(row + x0, row + x1 + 1, value);
    }
  };
  clear(centred_, std::uint8_t{0});
  clear(crossed_, std::uint8_t{0});
  clear(farthest_, -kNone);

  // Drawn triangles: the cells whose centres they hold, and their farthest corner in each cell
  // they touch (separating axes: the span's box axes, then the three edges' normals).
  for (std::size_t t = 0; t < triangles; ++t) {
    if (facing_[t] == 0) continue;
    const glm::dvec3& s0 = screen_[indices[t * 3]];
    const glm::dvec3& s1 = screen_[indices[t * 3 + 1]];
    const glm::dvec3& s2 = screen_[indices[t * 3 + 2]];
    const std::array<glm::dvec2, 3> v{glm::dvec2(s0), glm::dvec2(s1), glm::dvec2(s2)};
    const double area2 =
        (v[1].x - v[0].x) * (v[2].y - v[0].y) - (v[1].y - v[0].y) * (v[2].x - v[0].x);
    const double turn = area2 > 0.0 ? 1.0 : -1.0;
    const float far_w = static_cast<float>(std::max({s0.z, s1.z, s2.z}));
    int tx0 = 0, ty0 = 0, tx1 = 0, ty1 = 0;
    if (!cell_span(std::min({v[0].x, v[1].x, v[2].x}), std::min({v[0].y, v[1].y, v[2].y}),
                   std::max({v[0].x, v[1].x, v[2].x}), std::max({v[0].y, v[1].y, v[2].y}), columns_,
                   rows_, tx0, ty0, tx1, ty1))
      continue;
    // Edge k: inside where e_k(p) = turn * cross(v[k+1] - v[k], p - v[k]) >= 0.
    std::array<glm::dvec2, 3> normal{};
    std::array<double, 3> offset{};
    for (int k = 0; k < 3; ++k) {
      const glm::dvec2 d =
          v[static_cast<std::size_t>((k + 1) % 3)] - v[static_cast<std::size_t>(k)];
      normal[static_cast<std::size_t>(k)] = turn * glm::dvec2(-d.y, d.x);
      offset[static_cast<std::size_t>(k)] =
          glm::dot(normal[static_cast<std::size_t>(k)], v[static_cast<std::size_t>(k)]);
    }
    for (int y = ty0; y <= ty1; ++y) {
      for (int x = tx0; x <= tx1; ++x) {
        bool touches = true, holds_centre = true;
        const glm::dvec2 centre(x + 0.5, y + 0.5);
        for (std::size_t k = 0; k < 3; ++k) {
          // The grown cell's corner furthest along the edge's inward normal.
          const glm::dvec2 corner(normal[k].x >= 0.0 ? x + 1 + kSlack : x - kSlack,
                                  normal[k].y >= 0.0 ? y + 1 + kSlack : y - kSlack);
          if (glm::dot(normal[k], corner) < offset[k]) touches = false;
          if (glm::dot(normal[k], centre) < offset[k]) holds_centre = false;
        }
        if (!touches) continue;
        const std::size_t cell =
            static_cast<std::size_t>(y) * columns_ + static_cast<std::size_t>(x);
        farthest_[cell] = std::max(farthest_[cell], far_w);
        if (holds_centre) centred_[cell] = 1;
      }
    }
  }

  // The outline: edges between a drawn triangle and one not drawn (or drawn the other way
  // round, a fold of an open surface), and edges of the surface's border.
  const auto drawn = [&](std::int32_t t) {
    return t >= 0 && facing_[static_cast<std::size_t>(t)] != 0;
  };
  for (std::size_t e = 0; e < edges.vertices.size(); ++e) {
    const auto [t0, t1] = edges.triangles[e];
    const bool d0 = drawn(t0), d1 = drawn(t1);
    if (t1 != TriangleEdges::kNonManifold) {  // those are always outline
      if (!d0 && !d1) continue;
      if (d0 && d1 &&
          facing_[static_cast<std::size_t>(t0)] == facing_[static_cast<std::size_t>(t1)])
        continue;
    }
    const glm::dvec2 a(screen_[edges.vertices[e][0]]), b(screen_[edges.vertices[e][1]]);
    int ex0 = 0, ey0 = 0, ex1 = 0, ey1 = 0;
    if (!cell_span(std::min(a.x, b.x), std::min(a.y, b.y), std::max(a.x, b.x), std::max(a.y, b.y),
                   columns_, rows_, ex0, ey0, ex1, ey1))
      continue;
    for (int y = ey0; y <= ey1; ++y)
      for (int x = ex0; x <= ex1; ++x)
        if (segment_touches(a, b, x, y))
          crossed_[static_cast<std::size_t>(y) * columns_ + static_cast<std::size_t>(x)] = 1;
  }

  for (int y = y0; y <= y1; ++y) {
    for (int x = x0; x <= x1; ++x) {
      const std::size_t cell = static_cast<std::size_t>(y) * columns_ + static_cast<std::size_t>(x);
      if (centred_[cell] != 0 && crossed_[cell] == 0)
        eye.depth[cell] = std::min(eye.depth[cell], farthest_[cell]);
    }
  }
}

bool OccluderDepth::hides(const Aabb& box) const {
  if (columns_ == 0 || rows_ == 0 || box.empty()) return false;
  return hides_in(eyes_[0], box) && hides_in(eyes_[1], box);
}

bool OccluderDepth::hides_in(const Eye& eye, const Aabb& box) const {
  glm::dvec2 lo(std::numeric_limits<double>::infinity());
  glm::dvec2 hi(-std::numeric_limits<double>::infinity());
  double near = std::numeric_limits<double>::infinity();
  for (int c = 0; c < 8; ++c) {
    const glm::dvec3 p((c & 1) ? box.hi.x : box.lo.x, (c & 2) ? box.hi.y : box.lo.y,
                       (c & 4) ? box.hi.z : box.lo.z);
    const glm::dvec4 clip = eye.view_projection * glm::dvec4(p, 1.0);
    if (clip.w <= kNearest_w) return false;  // reaches the eye: no claim
    near = std::min(near, clip.w);
    const glm::dvec2 cell((clip.x / clip.w + 1.0) * 0.5 * columns_,
                          (clip.y / clip.w + 1.0) * 0.5 * rows_);
    lo = glm::min(lo, cell);
    hi = glm::max(hi, cell);
  }
  int x0 = 0, y0 = 0, x1 = 0, y1 = 0;
  // Wholly beside this eye's view: this eye sees none of it.
  if (!cell_span(lo.x, lo.y, hi.x, hi.y, columns_, rows_, x0, y0, x1, y1)) return true;
  const auto bound = static_cast<float>(near * (1.0 - kDepthMargin));
  for (int y = y0; y <= y1; ++y) {
    const float* row = eye.depth.data() + static_cast<std::size_t>(y) * columns_;
    for (int x = x0; x <= x1; ++x)
      if (!(row[x] < bound)) return false;
  }
  return true;
}

std::size_t OccluderDepth::covered_cells(int eye) const {
  const std::vector<float>& depth = eyes_[static_cast<std::size_t>(eye)].depth;
  return static_cast<std::size_t>(
      std::count_if(depth.begin(), depth.end(), [](float d) { return d < kNone; }));
}

}  // namespace bisturi::render
