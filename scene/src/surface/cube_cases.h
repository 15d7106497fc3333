#pragma once
// The triangulation of one marching-cubes cell, derived at start-up from first principles (no
// published table is copied): for each of the 256 inside/outside configurations of the corners,
// and for each outcome of the asymptotic decider on its ambiguous faces, the triangles that the
// cell contributes.
//
// Cell conventions. Corner c = x + 2y + 4z (x, y, z in {0, 1}) is sample (i+x, j+y, k+z); bit c of
// the case byte is 1 when that corner is inside (value > iso). Cube edges: 0..3 run along x at
// (y, z) = index bits, 4..7 along y at (x, z), 8..11 along z at (x, y). Faces: f = 2 * axis + side,
// side 0 at coordinate 0. A vertex code below 12 is the vertex on that cube edge; 12 + n is the
// n-th extra vertex of the entry, the centroid of a polygon that has no admissible diagonal
// triangulation (see cube_cases.cpp).

#include <array>
#include <cstdint>
#include <vector>

namespace bisturi::surface {

/// The corners of face f in cyclic order, counter-clockwise seen from outside the cell, and the
/// cube edge between corner m and corner m + 1 (mod 4).
struct CubeFace {
  std::array<std::uint8_t, 4> corners;
  std::array<std::uint8_t, 4> edges;
};

struct CaseEntry {
  std::uint32_t first_triangle = 0;  ///< into CubeCases::triangle_codes (3 codes each)
  std::uint32_t triangle_count = 0;
  std::uint32_t first_extra = 0;  ///< into CubeCases::extras
  std::uint32_t extra_count = 0;
};

/// An extra vertex: the average of the vertices with codes codes[first .. first + count).
struct ExtraVertex {
  std::uint32_t first_code = 0;
  std::uint32_t code_count = 0;
};

struct CubeCase {
  std::uint32_t first_entry = 0;     ///< entry for decider outcome bits b: first_entry + b
  std::uint8_t ambiguous_faces = 0;  ///< bit f: face f has two diagonal inside corners only
  std::uint8_t ambiguous_count = 0;
  std::uint16_t crossed_edges = 0;  ///< bit e: cube edge e is crossed
};

struct CubeCases {
  std::array<CubeFace, 6> faces{};
  /// The two corners of every cube edge (lower corner first).
  std::array<std::array<std::uint8_t, 2>, 12> edge_corners{};
  std::array<CubeCase, 256> cases{};
  std::vector<CaseEntry> entries;
  std::vector<std::uint8_t> triangle_codes;
  std::vector<ExtraVertex> extras;
  std::vector<std::uint8_t> extra_codes;
};

/// The tables, built once (thread-safe) on first use. Decider outcome bit b belongs to the b-th
/// ambiguous face in increasing face order; it is 1 when the face's two inside corners are joined
/// across the face (the bilinear saddle is inside).
const CubeCases& cube_cases();

/// Builds the polygons of one configuration (exposed for the tests): cycles of cube-edge codes,
/// each oriented so that its normal (right-hand rule) points from inside to outside.
std::vector<std::vector<std::uint8_t>> cell_polygons(std::uint8_t inside_corners,
                                                     std::uint8_t connected_faces);

}  // namespace bisturi::surface
