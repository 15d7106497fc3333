#pragma once
// validate(): checks every structural invariant of a Dlfl and says exactly what is broken.

#include <cstddef>
#include <string>
#include <vector>

#include "bisturi/scene/dlfl.h"

namespace bisturi {

struct ValidationReport {
  std::vector<std::string> problems;  ///< one line per broken invariant, naming the elements

  [[nodiscard]] bool ok() const { return problems.empty(); }
  /// All problems on one line each (empty when ok).
  [[nodiscard]] std::string summary() const;
};

/// Checks: next/prev consistency and closed face cycles; every corner in exactly one face
/// cycle and that face named in the corner; every side of every edge present and paired with
/// its opposite side; non-manifold pairs joining the same two vertices in distinct rotations;
/// every corner of a vertex in exactly one of its rotations; labels only on live faces; free
/// lists holding only deleted slots; no live element naming a dead one. Stops listing after
/// max_problems. Linear in the size of the structure.
ValidationReport validate(const Dlfl& mesh, std::size_t max_problems = 50);

}  // namespace bisturi
