// A finer drawn surface on a volume body (see drawn_surface.h).

#include "drawn_surface.h"

#include <algorithm>
#include <stdexcept>
#include <utility>

#include <glm/geometric.hpp>

#include "bisturi/sim/collision.h"
#include "bisturi/sim/cutting.h"
#include "bisturi/sim/errors.h"
#include "bisturi/sim/units.h"
#include "bisturi/sim/volume/lattice_cut.h"
#include "bisturi/sim/volume/volume_body.h"

namespace bisturi::runtime {

DrawnSurface::DrawnSurface(Dlfl drawn, const sim::SoftBody* simulated,
                           std::shared_ptr<const sim::HexLattice> lattice)
    : body_(std::move(drawn), simulated != nullptr ? simulated->material() : sim::Material{}),
      lattice_(std::move(lattice)) {
  if (!lattice_ || lattice_->cells.empty())
    throw std::invalid_argument("a drawn surface needs a volume lattice with cells");
  embed_all();
  follow(lattice_->rest);
  if (simulated != nullptr) anchor_to(*simulated);
}

void DrawnSurface::anchor_to(const sim::SoftBody& simulated) {
  // Each drawn vertex's closest point on the simulated surface at rest.
  const sim::CollisionDevice device;
  const sim::SurfaceBvh bvh(device, simulated);
  const sim::SurfaceTriangles& triangles = simulated.triangles();
  const std::vector<glm::dvec3>& x = body_.positions();
  anchor_.resize(x.size());
  std::vector<glm::dvec3> simulated_mm(simulated.positions().size());
  for (std::size_t i = 0; i < simulated_mm.size(); ++i)
    simulated_mm[i] = sim::sim_to_scene(simulated.positions()[i]);
  for (std::size_t v = 0; v < x.size(); ++v) {
    const sim::SurfacePoint p = bvh.closest_point(simulated, x[v]);
    if (!p.found) continue;
    SurfaceAnchor& a = anchor_[v];
    for (std::size_t k = 0; k < 3; ++k)
      a.slot[k] = triangles.indices[3 * p.triangle + k];
    a.weights = p.barycentric;
  }
  rest_gap_mm_ = gap_mm(simulated_mm);
}

void DrawnSurface::embed_all() {
  const std::size_t slots = body_.positions().size();
  embedding_.resize(slots);
  for (std::size_t v = 0; v < slots; ++v)
    embed(v);
}

void DrawnSurface::embed(std::size_t v) {
  const VertexId id{static_cast<std::uint32_t>(v)};
  if (!body_.mesh().alive(id)) return;
  embedding_[v] = *sim::embed_point_on_side(*lattice_, body_.rest_position(id),
                                            v < side_.size() ? side_[v] : 0);
}

void DrawnSurface::use_lattice(const std::shared_ptr<const sim::HexLattice>& lattice) {
  if (!lattice || lattice == lattice_) return;
  lattice_ = lattice;
  embed_all();
}

void DrawnSurface::follow(std::span<const glm::dvec3> nodes_m) {
  if (nodes_m.size() != lattice_->rest.size()) return;  // a snapshot of another lattice
  std::vector<glm::dvec3>& x = body_.positions();
  for (std::size_t v = 0; v < x.size(); ++v)
    x[v] = sim::embedded_position(*lattice_, nodes_m, embedding_[v]);
  body_.write_positions_to_scene();
}

bool DrawnSurface::cut(std::span<const glm::dvec3> points_m, std::span<const glm::dvec3> tips_m) {
  sim::CutResult result;
  try {
    sim::CutOptions options;
    options.blade_tips_m = tips_m;
    result = sim::cut_surface(body_, points_m, options);
  } catch (const sim::CutError&) {
    return false;
  }
  // The far lip's copies keep their originals' closest points on the simulated surface. Where
  // the volume was separated along the cut each lip follows the cells on its side; elsewhere
  // the copies stand in their originals' cells.
  const std::size_t had = embedding_.size();
  const std::size_t slots = body_.positions().size();
  embedding_.resize(slots);
  anchor_.resize(slots);
  for (const VertexId copy : result.new_vertices) {
    for (const VertexId original : result.path) {
      if (body_.rest_position(original) != body_.rest_position(copy)) continue;
      embedding_[copy.idx] = embedding_[original.idx];
      anchor_[copy.idx] = anchor_[original.idx];
      lips_.emplace_back(original.idx, copy.idx);
      break;
    }
  }
  // Where the cut parted the volume, each lip goes into a cell on its side, and every vertex the
  // cut made (the copies, the walls' floor) where it lies; the others keep their cells.
  if (!lattice_->cut_sheet.empty()) {
    const std::vector<std::int8_t> lips = sim::lip_sides(body_, result, *lattice_);
    side_.resize(slots, 0);
    for (std::size_t v = 0; v < slots; ++v) {
      if (lips[v] == 0) continue;
      side_[v] = lips[v];
      embed(v);
    }
    for (std::size_t v = had; v < slots; ++v)
      embed(v);
  } else {
    for (const VertexId floor : result.floor_vertices)
      embed(floor.idx);
  }
  body_.write_positions_to_scene();
  ++cuts_;
  return true;
}

double DrawnSurface::opening_mm() const {
  double widest = 0.0;
  const auto& x = body_.mesh().positions();
  for (const auto& [a, b] : lips_)
    widest = std::max(widest, glm::length(x[a] - x[b]));
  return widest;
}

double DrawnSurface::gap_mm(std::span<const glm::dvec3> simulated_mm) const {
  double most = 0.0;
  const auto& drawn = body_.mesh().positions();
  for (std::size_t v = 0; v < anchor_.size() && v < drawn.size(); ++v) {
    const SurfaceAnchor& a = anchor_[v];
    if (a.weights == glm::dvec3(0.0)) continue;
    if (std::max({a.slot[0], a.slot[1], a.slot[2]}) >= simulated_mm.size()) continue;
    const glm::dvec3 on = a.weights.x * simulated_mm[a.slot[0]] +
                          a.weights.y * simulated_mm[a.slot[1]] +
                          a.weights.z * simulated_mm[a.slot[2]];
    most = std::max(most, glm::length(drawn[v] - on));
  }
  return most;
}

}  // namespace bisturi::runtime
