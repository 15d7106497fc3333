// Ambient occlusion between the parts of the field (see field_occlusion.h).

#include "field_occlusion.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <limits>

#include <glm/common.hpp>
#include <glm/geometric.hpp>

#include "bisturi/runtime/render/drape_mesh.h"
#include "bisturi/runtime/render/frustum.h"
#include "bisturi/sim/collision.h"
#include "bisturi/sim/units.h"

namespace bisturi::runtime {

namespace {

/// Each alive vertex's normal: its faces' Newell normals summed (zero for a dead vertex).
std::vector<glm::dvec3> vertex_normals(const Dlfl& mesh) {
  std::vector<glm::dvec3> n(mesh.vertex_capacity(), glm::dvec3(0.0));
  for (std::uint32_t f = 0; f < mesh.face_capacity(); ++f) {
    const FaceId id{f};
    if (!mesh.alive(id) || mesh.is_bounding(id)) continue;
    // Newell's normal: robust for any polygon, its length twice the area.
    glm::dvec3 fn(0.0);
    const CornerId first = mesh.first_corner(id);
    CornerId c = first;
    do {
      const glm::dvec3& a = mesh.position(mesh.vertex(c));
      const glm::dvec3& b = mesh.position(mesh.vertex(mesh.next(c)));
      fn += glm::dvec3((a.y - b.y) * (a.z + b.z), (a.z - b.z) * (a.x + b.x),
                       (a.x - b.x) * (a.y + b.y));
      c = mesh.next(c);
    } while (c != first);
    c = first;
    do {
      n[mesh.vertex(c).idx] += fn;
      c = mesh.next(c);
    } while (c != first);
  }
  return n;
}

/// Unit directions about +z, cosine-weighted (a Fibonacci spiral over the disc, lifted).
std::vector<glm::dvec3> hemisphere(int count) {
  std::vector<glm::dvec3> out;
  const double golden = 3.14159265358979323846 * (3.0 - std::sqrt(5.0));
  for (int i = 0; i < count; ++i) {
    const double r = std::sqrt((i + 0.5) / count);
    const double a = golden * i;
    out.emplace_back(r * std::cos(a), r * std::sin(a), std::sqrt(std::max(0.0, 1.0 - r * r)));
  }
  return out;
}

/// Body b's box at its positions now (mm).
render::Aabb body_box(const sim::SimWorld& world, std::uint32_t b) {
  render::Aabb box;
  for (const glm::dvec3& x : world.body(b).positions())
    box.extend(sim::sim_to_scene(x));
  return box;
}

/// All the bodies' box (mm).
render::Aabb world_box(const sim::SimWorld& world) {
  render::Aabb box;
  for (std::uint32_t b = 0; b < world.body_count(); ++b)
    box.extend(body_box(world, b));
  return box;
}

/// Whether p lies within `reach` of the box.
bool within(const render::Aabb& box, const glm::dvec3& p, double reach) {
  const glm::dvec3 gap = glm::max(glm::max(box.lo - p, p - box.hi), glm::dvec3(0.0));
  return glm::dot(gap, gap) <= reach * reach;
}

}  // namespace

std::vector<float> field_occlusion(const Dlfl& receiver, const sim::SimWorld& world,
                                   std::int32_t own_body, double drape_z_mm,
                                   const OcclusionOptions& options) {
  const std::vector<glm::dvec3> normals = vertex_normals(receiver);
  const std::vector<glm::dvec3> dirs = hemisphere(options.rays);
  std::vector<render::Aabb> boxes;
  for (std::uint32_t b = 0; b < world.body_count(); ++b)
    boxes.push_back(body_box(world, b));
  const double reach = options.reach_mm;
  std::vector<float> open(receiver.vertex_capacity(), 1.0f);
  std::vector<std::uint32_t> near;  // the bodies within reach of a vertex
  for (std::uint32_t v = 0; v < receiver.vertex_capacity(); ++v) {
    if (!receiver.alive(VertexId(v))) continue;
    const double len = glm::length(normals[v]);
    if (!(len > 0.0)) continue;
    const glm::dvec3 n = normals[v] / len;
    const glm::dvec3 p = receiver.position(VertexId(v));
    near.clear();
    for (std::uint32_t b = 0; b < world.body_count(); ++b)
      if (static_cast<std::int32_t>(b) != own_body && within(boxes[b], p, reach)) near.push_back(b);
    const bool drape_near = p.z - drape_z_mm < reach;
    if (near.empty() && !drape_near) continue;
    // A frame about the normal.
    const glm::dvec3 t = glm::normalize(std::abs(n.x) < 0.9 ? glm::cross(n, glm::dvec3(1, 0, 0))
                                                            : glm::cross(n, glm::dvec3(0, 1, 0)));
    const glm::dvec3 bt = glm::cross(n, t);
    const glm::dvec3 from = p + 0.05 * n;
    double hidden = 0.0;
    for (const glm::dvec3& d : dirs) {
      const glm::dvec3 dir = d.x * t + d.y * bt + d.z * n;
      double nearest = reach;
      if (drape_near && dir.z < 0.0) nearest = std::min(nearest, (drape_z_mm - from.z) / dir.z);
      for (const std::uint32_t b : near) {
        const sim::SurfacePoint hit = world.bvh(b).ray(world.body(b), sim::scene_to_sim(from),
                                                       sim::scene_to_sim(from + nearest * dir));
        if (hit.found)
          nearest = std::min(nearest, glm::length(sim::sim_to_scene(hit.point_m) - from));
      }
      if (nearest < reach) hidden += 1.0 - nearest / reach;
    }
    open[v] =
        static_cast<float>(1.0 - options.strength * hidden / static_cast<double>(dirs.size()));
  }
  return open;
}

std::vector<float> lamp_light(const Dlfl& receiver, const sim::SimWorld& world,
                              const OcclusionOptions& options) {
  // Rays up through the lamp's disc: the hemisphere's directions squeezed into the cone.
  const double spread = std::sin(options.lamp_half_angle_deg * 3.14159265358979323846 / 180.0);
  std::vector<glm::dvec3> dirs;
  for (const glm::dvec3& d : hemisphere(options.rays))
    dirs.push_back(glm::normalize(glm::dvec3(d.x * spread, d.y * spread, 1.0)));
  const render::Aabb all = world_box(world);
  std::vector<float> lit(receiver.vertex_capacity(), 1.0f);
  if (all.empty()) return lit;
  const double height = all.hi.z;  // above it nothing hides the lamp
  for (std::uint32_t v = 0; v < receiver.vertex_capacity(); ++v) {
    if (!receiver.alive(VertexId(v))) continue;
    const glm::dvec3 p = receiver.position(VertexId(v));
    const double rise = height - p.z;
    if (rise <= 0.0) continue;
    // Beside the solids' box by more than the cone widens over their height: in full light.
    const glm::dvec2 gap =
        glm::max(glm::max(glm::dvec2(all.lo) - glm::dvec2(p), glm::dvec2(p) - glm::dvec2(all.hi)),
                 glm::dvec2(0.0));
    if (glm::length(gap) > rise * spread / std::sqrt(1.0 - spread * spread)) continue;
    int hidden = 0;
    for (const glm::dvec3& dir : dirs) {
      const glm::dvec3 to = p + dir * (rise / dir.z);
      for (std::uint32_t b = 0; b < world.body_count(); ++b) {
        if (world.bvh(b).ray(world.body(b), sim::scene_to_sim(p), sim::scene_to_sim(to)).found) {
          ++hidden;
          break;
        }
      }
    }
    lit[v] = static_cast<float>(1.0 - options.shadow_strength * hidden /
                                          static_cast<double>(dirs.size()));
  }
  return lit;
}

FieldShading shade_field(const sim::SimWorld& world, const std::vector<const Dlfl*>& drawn,
                         double below_mm, const OcclusionOptions& options) {
  const auto begin = std::chrono::steady_clock::now();
  FieldShading out;
  const render::Aabb all = world_box(world);
  if (all.empty()) return out;
  const glm::dvec3& lo = all.lo;
  const glm::dvec3& hi = all.hi;
  // 24 x 24 quads (about 26 mm for the liver scene): the shading is soft at that scale, and on
  // lavapipe each finer step of the sheet cost the frame about a millisecond (72 x 72: 4.5 ms).
  out.drape = render::drape_sheet(lo, hi, below_mm, 1.0, 24);
  out.drape_z_mm = lo.z - below_mm;
  out.drape_open =
      field_occlusion(out.drape, world, -1, -std::numeric_limits<double>::infinity(), options);
  // Its soft shadow under the lamp where that is darker than the sky it misses.
  const std::vector<float> lit = lamp_light(out.drape, world, options);
  for (std::size_t v = 0; v < out.drape_open.size(); ++v)
    out.drape_open[v] = std::min(out.drape_open[v], lit[v]);
  for (std::uint32_t b = 0; b < world.body_count(); ++b) {
    const Dlfl* mesh = b < drawn.size() ? drawn[b] : nullptr;
    if (mesh != nullptr) {
      out.solid_open.push_back(
          field_occlusion(*mesh, world, static_cast<std::int32_t>(b), out.drape_z_mm, options));
      continue;
    }
    // The body's own surface at its positions now (millimetres), by slot.
    Dlfl surface = world.body(b).mesh();
    for (std::size_t v = 0; v < surface.vertex_capacity(); ++v)
      surface.positions()[v] = sim::sim_to_scene(world.body(b).positions()[v]);
    out.solid_open.push_back(
        field_occlusion(surface, world, static_cast<std::int32_t>(b), out.drape_z_mm, options));
  }
  out.build_ms =
      std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - begin).count();
  return out;
}

}  // namespace bisturi::runtime
