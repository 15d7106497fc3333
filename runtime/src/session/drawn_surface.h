#pragma once
// A solid drawn finer than it is simulated. The scan's surface at a finer resolution rides on the
// volume body: each of its vertices is embedded in the body's lattice (trilinear weights in its
// cell at rest, sim/volume/embedding.h) and moves with the nodes the tissue step solves, while
// contact, grasping and cutting in the simulation use the coarse surface the step can afford.
// Each cut the simulation makes is made on the drawn surface too, along the same blade points
// (the same sim::cut_surface), and its new vertices are embedded where their originals are, as
// the simulated surface's are: both lips follow the same cells.
//
// How far apart the two surfaces are: each drawn vertex keeps its closest point on the simulated
// surface at rest (three vertex slots and barycentric weights); gap_mm() measures the distance
// between the vertex and that point as both surfaces are now.

#include <array>
#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/scene/dlfl.h"
#include "bisturi/sim/soft_body.h"
#include "bisturi/sim/volume/embedding.h"
#include "bisturi/sim/volume/hex_lattice.h"

namespace bisturi::runtime {

class DrawnSurface {
 public:
  /// `drawn` in scene millimetres; `simulated` the body it stands for, at rest (null: a
  /// structure inside it, which has no gap to it); `lattice` the body's volume lattice. Throws
  /// std::invalid_argument for a lattice without cells.
  DrawnSurface(Dlfl drawn, const sim::SoftBody* simulated,
               std::shared_ptr<const sim::HexLattice> lattice);

  /// The lattice the nodes now belong to (a new one after the refined box moved): every vertex
  /// is embedded again at its rest position. Nothing when it is the one in use.
  void use_lattice(const std::shared_ptr<const sim::HexLattice>& lattice);
  /// Positions from the lattice's nodes now (metres) into positions_mm().
  void follow(std::span<const glm::dvec3> nodes_m);
  /// Cuts along an incision's blade points (metres), at the positions follow() gave last; with
  /// the blade's tips (as many), the wound gets walls down to them (sim::CutOptions). False
  /// when they give no path on this surface (sim::CutError): it stays as it was.
  bool cut(std::span<const glm::dvec3> points_m, std::span<const glm::dvec3> tips_m = {});

  /// The largest distance (mm) between a drawn vertex and its closest point on the simulated
  /// surface at rest, that point carried by the simulated vertices now (by slot, mm).
  [[nodiscard]] double gap_mm(std::span<const glm::dvec3> simulated_mm) const;
  /// gap_mm at rest.
  [[nodiscard]] double rest_gap_mm() const { return rest_gap_mm_; }
  /// What is drawn: the surface at the positions of the last follow() (mm). A cut adds
  /// vertices and faces; the vertices it had keep their indices.
  [[nodiscard]] const Dlfl& mesh() const { return body_.mesh(); }
  /// Cuts made on it so far.
  [[nodiscard]] std::uint64_t cuts() const { return cuts_; }
  /// How far the cuts have opened (mm): the widest distance now between a vertex on a cut's
  /// path and its copy on the other lip. 0 before any cut.
  [[nodiscard]] double opening_mm() const;
  [[nodiscard]] std::size_t vertices() const { return body_.mesh().num_vertices(); }
  [[nodiscard]] std::size_t faces() const { return body_.mesh().num_faces(); }

 private:
  /// A point on the simulated surface: its triangle's vertex slots and barycentric weights.
  struct SurfaceAnchor {
    std::array<std::uint32_t, 3> slot{};
    glm::dvec3 weights{0.0};
  };
  void embed_all();
  /// Vertex slot v in its cell of the lattice, on its side of the cuts (nothing for a dead slot).
  void embed(std::size_t v);
  /// Each vertex's closest point on `simulated` (at rest), and the gap at rest.
  void anchor_to(const sim::SoftBody& simulated);

  /// Only its mesh (what is drawn, in mm), rest and current positions are used:
  /// sim::cut_surface cuts it.
  sim::SoftBody body_;
  std::shared_ptr<const sim::HexLattice> lattice_;
  std::vector<sim::EmbeddedPoint> embedding_;  ///< by vertex slot
  /// By vertex slot: the side of the lattice's cuts a lip of a cut belongs to (0: not a lip).
  std::vector<std::int8_t> side_;
  /// Each cut's opened path vertices and their copies (vertex slots).
  std::vector<std::pair<std::uint32_t, std::uint32_t>> lips_;
  std::vector<SurfaceAnchor> anchor_;  ///< by vertex slot
  std::uint64_t cuts_ = 0;
  double rest_gap_mm_ = 0.0;
};

/// A structure inside a volume solid ([[solids.inner]]), riding on its volume.
struct InnerStructure {
  std::size_t solid = 0;  ///< the solid it lies in
  std::array<double, 3> colour{};
  std::unique_ptr<DrawnSurface> surface;
};

}  // namespace bisturi::runtime
