#pragma once
// Any polygon mesh into the DLFL: the construction of the seed's section 4.4 (procedures 3-6),
// with the cases the seed left open closed.
//
// 3. Welding: soups (no vertex list, e.g. STL) always weld equal coordinates through a hash
//    (linear time); indexed input keeps its vertex indices unless asked to weld (the two lips of
//    a fresh incision are two vertices at one place). A tolerance welds within a distance.
// 4. Orientation and parts: a stack walk across edges shared by exactly two faces orients every
//    face like its neighbour; edges in one face are boundary, edges in three or more faces are
//    non-manifold and not crossed. A part that cannot be oriented (a Moebius strip) is reported
//    and cut along the edge where the walk met itself, so it can still be stored.
// 5. Fans: the faces around a vertex that are joined through such edges form a fan; a vertex
//    with several fans (a junction between parts, or a bow-tie inside one part) gets one DLFL
//    rotation per fan (add_rotation), so no face degenerates.
// 6. Insertion with the DLFL operators; every boundary loop becomes a labelled face.
//
// The common input, manifold surfaces whose faces already agree in orientation (every edge in one
// face, or in two running it opposite ways; one fan per vertex), closed or with boundary, skips
// 4-6: its DLFL is written directly in one pass, with its boundary loops as labelled faces, the
// same structure and report the general path gives it. Anything else (a flip, a non-manifold
// edge, a bow-tie) is detected there and takes the general path.
//
// Faces with fewer than three distinct vertices, a vertex repeated on consecutive corners, or
// zero area are dropped and listed with their reason; every other input face appears in the DLFL
// as one face with the same cycle of vertices (reversed for the flipped ones).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/scene/dlfl.h"
#include "bisturi/scene/oriented_builder.h"

namespace bisturi {

struct ImportOptions {
  /// Weld indexed vertices at equal coordinates (soups are always welded).
  bool weld = false;
  /// Greater than zero: weld vertices closer than this distance (model units); implies weld.
  double weld_tolerance = 0.0;
  /// Insert with the DLFL operators one edge at a time (the seed's procedure 6, literally)
  /// instead of writing the same final structure in one linear pass.
  bool use_operators = false;
  /// Called with a stage name and (done, total) while the work is long.
  std::function<void(std::string_view stage, std::size_t done, std::size_t total)> progress;
};

enum class DropReason : std::uint8_t {
  TooFewDistinctVertices,     ///< fewer than three distinct vertices
  RepeatedConsecutiveVertex,  ///< the same index twice in a row (a zero-length side)
  ZeroArea,                   ///< all corners on one line (or one point)
};
std::string_view to_string(DropReason reason);

struct DroppedFace {
  std::uint32_t face;  ///< index in the input
  DropReason reason;
};

/// One part as procedure 4 defines it: faces connected through edges in exactly two faces.
struct ImportPart {
  std::size_t faces = 0;
  std::size_t vertices = 0;
  std::size_t edges = 0;
  bool closed = false;  ///< no edge of the part lies in only one of its faces
  std::size_t boundary_loops = 0;
  bool orientable = true;
  std::int64_t euler = 0;             ///< V - E + F on the part's own elements
  std::optional<std::int64_t> genus;  ///< orientable parts only: (2 - euler - loops) / 2
};

struct ImportReport {
  std::size_t input_vertices = 0;
  std::size_t input_faces = 0;
  std::size_t welded_vertices = 0;    ///< input vertices merged into another one
  std::size_t vertices = 0;           ///< used by kept faces (after welding)
  std::size_t isolated_vertices = 0;  ///< used by no kept face (kept as lone vertices)
  std::size_t edges = 0;              ///< distinct unordered vertex pairs of kept faces
  std::size_t faces = 0;              ///< kept faces
  std::vector<DroppedFace> dropped;
  std::size_t nonmanifold_edges = 0;     ///< edges in three or more faces
  std::size_t nonmanifold_vertices = 0;  ///< on a non-manifold edge, or with several fans
  std::size_t flipped_faces = 0;         ///< reversed to agree with their neighbours
  std::size_t duplicate_faces = 0;       ///< same vertex cycle as an earlier face (kept)
  std::size_t seam_edges = 0;            ///< cut to store non-orientable parts
  std::vector<ImportPart> parts;
};

struct ImportResult {
  Dlfl mesh;
  ImportReport report;
  std::vector<VertexId> vertex_of_input;  ///< DLFL vertex of every input vertex
  std::vector<FaceId> face_of_input;      ///< DLFL face of every input face (invalid: dropped)
  std::vector<char> flipped;              ///< per input face: stored reversed
};

/// Builds the DLFL of any polygon mesh. Throws InputError (naming the face or vertex) only for
/// input that cannot be interpreted: an index out of range or a non-finite coordinate.
ImportResult import_polygons(const PolygonMesh& in, bool has_vertex_list,
                             const ImportOptions& options = {});

}  // namespace bisturi
