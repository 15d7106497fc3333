#pragma once
// A cut through a solid's volume: the lattice's cells are separated along the faces the blade's
// sheet passes between, so the tissue on either side moves apart under its own tension and the
// wound opens. A face is separated when the segment between its two cells' centres crosses the
// sheet; the nodes of separated faces are copied, one copy per group of cells still joined
// around the node through faces, so a cell keeps its 8 corners and the crack's front (where
// the sheet ends inside) stays joined. This is the virtual node algorithm's separation
// (Molino, Bao and Fedkiw 2004, section 3) with the cut moved onto the nearest cell faces
// instead of through the cells: the wound's surface is drawn where the blade went (the DLFL
// cut) and each of its vertices follows a cell on its own side (embed_point_on_side).

#include <array>
#include <cstdint>
#include <vector>

#include <glm/vec3.hpp>

#include "bisturi/sim/volume/embedding.h"
#include "bisturi/sim/volume/hex_lattice.h"

namespace bisturi::sim {

/// What a blade swept: per sample, where its edge crossed the surface and where its tip was
/// (the lattice's rest frame, metres). Consecutive samples bound a quad of the sheet.
struct BladeSheet {
  std::vector<glm::dvec3> entry_m;
  std::vector<glm::dvec3> tip_m;
};

struct LatticeSeparation {
  /// Per node of the separated lattice, the node it was copied from (itself for the old ones).
  std::vector<std::uint32_t> origin;
  std::size_t separated_faces = 0;
  std::size_t new_nodes = 0;
};

/// Separates `lattice` along `sheet` (extended `reach_m` out of the surface beyond each entry
/// point, so cells holding little tissue are parted too), adding its triangles to
/// lattice.cut_sheet. In a two-level lattice a face parts between two cells of one size, where
/// none of its nodes hangs or is shared with a cell of the other size. Throws std::invalid_argument
/// for a sheet of fewer than two samples.
LatticeSeparation separate_along_sheet(HexLattice& lattice, const BladeSheet& sheet,
                                       double reach_m);

/// Which side of the lattice's cut sheets `p` lies on: +1 or -1 by the nearest sheet
/// triangle's orientation (+1 where there is no sheet).
int sheet_side(const HexLattice& lattice, const glm::dvec3& p);

/// The point's cell and weights at rest, on `side` of the cuts (+1 or -1; 0: the side it lies
/// on): a point whose cell lies across a separated face from it takes the nearest cell on its
/// side across that face, its weights extrapolated. Away from a cut, embed_point_nearest.
std::optional<EmbeddedPoint> embed_point_on_side(const HexLattice& lattice, const glm::dvec3& point,
                                                 int side);

}  // namespace bisturi::sim
