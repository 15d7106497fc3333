#pragma once
// A lattice of hexahedral cells filling a closed surface: the volume under a tissue solid's DLFL.
// The lattice is rectilinear (each axis has its own node coordinates), graded towards a focus
// (the cells are finest there and grow geometrically away from it), so the resolution sits
// where an instrument touches and the rest stays coarse without hanging nodes: every cell is a
// box, and neighbouring boxes share their faces whole. A cell is kept when any of it lies inside
// the surface (its fill, the share of its volume inside, weights its stiffness, as SOFA's
// SparseGridTopology does) or when a surface vertex lies in it, so every surface vertex can be
// embedded (volume/embedding.h).

#include <array>
#include <cmath>
#include <cstdint>
#include <span>
#include <vector>

#include <glm/vec3.hpp>

namespace bisturi::sim {

struct LatticeOptions {
  double finest_m = 0.001;         ///< cell size at the focus
  double coarsest_m = 0.004;       ///< the largest cell size grading reaches
  double growth = 1.3;             ///< ratio of neighbouring cell sizes away from the fine region
  glm::dvec3 focus_m{0.0};         ///< where the cells are finest
  double fine_half_width_m = 0.0;  ///< cells stay finest within this distance of the focus
  int fill_samples = 3;            ///< per axis and cell, for the inside share
  /// The solid is cut at this height: no cell below it (a rigid plane it stands on).
  double floor_z_m = -INFINITY;
  /// Cells next to the floor no taller than this, growing away from it (0: no limit).
  double floor_cell_m = 0.0;
};

/// A node of a fine cell that lies on a face or an edge of a coarser neighbour without being one
/// of its corners: it is not free, but follows that face or edge (its position, velocity and
/// every motion are its masters' by bilinear or linear weights), so the fine and the coarse
/// cells stay joined. The solve works on the free nodes only (BlockMatrix::solve).
struct HangingNode {
  std::uint32_t node = 0;
  std::uint32_t masters_count = 0;  ///< 2 on an edge, 4 on a face
  std::array<std::uint32_t, 4> masters{};
  std::array<double, 4> weights{};
};

struct HexLattice {
  /// Node coordinates along x, y and z (rest, metres): node (i, j, k) is at
  /// (axis[0][i], axis[1][j], axis[2][k]).
  std::array<std::vector<double>, 3> axis;
  std::vector<glm::dvec3> rest;  ///< the nodes the kept cells use
  /// Each kept cell's 8 nodes; corner c is at offset (c & 1, (c >> 1) & 1, (c >> 2) & 1).
  std::vector<std::array<std::uint32_t, 8>> cells;
  std::vector<std::array<std::uint32_t, 3>> cell_ijk;  ///< the cell's lattice position
  std::vector<double> fill;  ///< share of each cell's volume inside the surface, (0, 1]
  /// The kept cell at lattice position (i, j, k), or -1: cell_at[(k * ny + j) * nx + i]. A
  /// cell spanning several positions is at each of them.
  std::vector<std::int32_t> cell_at;
  /// Per cell, how many lattice positions it spans along each axis (a coarse cell of a
  /// two-level lattice); empty: every cell spans one.
  std::vector<std::uint32_t> cell_span;
  /// The nodes that follow a coarser neighbour's face or edge (a two-level lattice's).
  std::vector<HangingNode> hanging;
  /// Per cell, the faces a cut separated it from its neighbour along (bit 2a: its face at the
  /// low end of axis a, bit 2a + 1: at the high end; lattice_cut.h); empty: no cut.
  std::vector<std::uint8_t> separated;
  /// The cuts' sheets as triangles (rest, metres), each wound as its blade went.
  std::vector<std::array<glm::dvec3, 3>> cut_sheet;

  [[nodiscard]] std::uint32_t span(std::size_t cell) const {
    return cell_span.empty() ? 1u : cell_span[cell];
  }
  /// Cell c's sides (metres).
  [[nodiscard]] glm::dvec3 cell_sides(std::size_t c) const;
  /// Cell c's centre at rest (metres).
  [[nodiscard]] glm::dvec3 cell_centre(std::size_t c) const;

  [[nodiscard]] std::array<std::size_t, 3> cell_dims() const {
    return {axis[0].size() - 1, axis[1].size() - 1, axis[2].size() - 1};
  }
  /// The lattice cell (kept or not) containing p, clamped to the lattice's bounds.
  [[nodiscard]] std::array<std::uint32_t, 3> locate(const glm::dvec3& p) const;
  /// The kept cell containing p, or -1.
  [[nodiscard]] std::int32_t kept_cell(const glm::dvec3& p) const;
};

struct TwoLevelOptions {
  struct Box {
    glm::dvec3 lo{0.0}, hi{0.0};
  };
  double coarse_m = 0.004;   ///< the cells' side
  std::uint32_t factor = 2;  ///< each refined cell is split into factor^3
  std::vector<Box> refine;   ///< the cells meeting any of these boxes are split
  int fill_samples = 3;      ///< per axis and fine cell
  /// The solid is cut at this height: no cell below it (a rigid plane it stands on).
  double floor_z_m = -INFINITY;
};

/// The share of each fine cell of a two-level lattice's grid that lies inside the surface (ray
/// parity, fill_samples^3 samples a cell): the costly part of a build, and the same for every
/// build over one solid, whatever the boxes, since a cut does not change what is inside.
struct FineShares {
  glm::dvec3 lo{0.0};                 ///< the grid's low corner
  std::array<std::size_t, 3> dims{};  ///< fine cells per axis
  double fine_m = 0.0;
  int samples = 0;
  std::vector<double> share;  ///< (k * dims[1] + j) * dims[0] + i
};

/// The fine grid's shares for build_two_level_lattice with these options (refine is unused).
/// Throws as that does.
FineShares two_level_fine_shares(std::span<const glm::dvec3> vertices,
                                 std::span<const std::array<std::uint32_t, 3>> triangles,
                                 const TwoLevelOptions& options);

/// A lattice of two resolutions: cells of coarse_m over the closed surface, but those meeting
/// a refine box split into factor^3 cells, the fine nodes on the faces between the two sizes
/// hanging on the coarse cells' corners. Cells are kept as build_hex_lattice keeps them.
/// `shares` (may be null): the fine grid's shares from an earlier call over the same solid,
/// used when its grid is this build's (else they are computed). Throws std::invalid_argument on
/// an empty surface or bad options.
HexLattice build_two_level_lattice(std::span<const glm::dvec3> vertices,
                                   std::span<const std::array<std::uint32_t, 3>> triangles,
                                   const TwoLevelOptions& options,
                                   std::span<const glm::dvec3> also_embed = {},
                                   const FineShares* shares = nullptr);

/// Node coordinates from lo to hi: cells of `finest` within fine_half_width of `centre`, then
/// each `growth` times the last up to `coarsest`; with lo_cell > 0 the cells shrink again
/// towards lo, to lo_cell there. The ends land exactly on lo and hi.
std::vector<double> graded_axis(double lo, double hi, double centre, double finest,
                                double fine_half_width, double growth, double coarsest,
                                double lo_cell = 0.0);

/// The lattice filling the closed, consistently oriented triangle surface (any winding: inside
/// is decided by ray parity). Throws std::invalid_argument on an empty surface or bad options.
/// Cells holding a surface vertex or one of `also_embed` (points on the surface to embed besides
/// the vertices, e.g. contact samples) are kept too.
HexLattice build_hex_lattice(std::span<const glm::dvec3> vertices,
                             std::span<const std::array<std::uint32_t, 3>> triangles,
                             const LatticeOptions& options,
                             std::span<const glm::dvec3> also_embed = {});

}  // namespace bisturi::sim
