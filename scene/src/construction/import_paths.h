#pragma once
// Internal: the two paths of import_polygons(), for the tests that hold them against each other.

#include <optional>

#include "bisturi/scene/polygon_import.h"

namespace bisturi::construction {

enum class ImportPath {
  kAuto,     ///< the fast path where it applies, the general path otherwise (import_polygons)
  kGeneral,  ///< orient, rotation system and assembler for every input
  kFast,     ///< consistently oriented manifolds written directly; nullopt otherwise
};

/// import_polygons() along the given path. nullopt only for kFast on input it does not take.
std::optional<ImportResult> import_polygons_via(const PolygonMesh& in, bool has_vertex_list,
                                                const ImportOptions& options, ImportPath path);

}  // namespace bisturi::construction
