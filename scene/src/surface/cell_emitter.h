#pragma once
// Marching cubes (marching_cubes.cpp): the output of one mixed cell. The asymptotic decider picks
// the case entry (cube_cases.h), the entry's extra (centroid) vertices are made, and the sink gets
// the entry's triangles with the cell's vertex ids.

#include <array>
#include <cstddef>
#include <cstdint>

#include <glm/vec3.hpp>

#include "bisturi/scene/volume/marching_cubes.h"
#include "bisturi/scene/volume/volume.h"
#include "cube_cases.h"
#include "extraction_sinks.h"

namespace bisturi::surface {

class CellEmitter {
 public:
  CellEmitter(const Grid<float>& volume, float iso, const CubeCases& cases, ExtractionStats& stats)
      : values_(volume.values.data()),
        iso_(iso),
        cases_(cases),
        stats_(stats),
        nx_(volume.geometry.dims[0]),
        plane_(nx_ * volume.geometry.dims[1]) {
    for (int c = 0; c < 8; ++c) {
      corner_offset_[static_cast<std::size_t>(c)] =
          (c & 1) + nx_ * ((c >> 1) & 1) + plane_ * ((c >> 2) & 1);
    }
  }

  /// Emits cell (i, j, k) of case `config`; `ids` holds the vertex ids of its 12 cube edges and
  /// receives those of the extra vertices after them.
  template <class Sink>
  void emit(unsigned config, std::int64_t i, std::int64_t j, std::int64_t k, CellIds& ids,
            Sink& sink) {
    const std::uint32_t e =
        entry_index(config, i, j, k, Sink::kStats ? &stats_.ambiguous_faces : nullptr);
    const CaseEntry& entry = cases_.entries[e];
    for (std::uint32_t n = 0; n < entry.extra_count; ++n) {
      if constexpr (Sink::kPlaces) {
        const ExtraVertex& ev = cases_.extras[entry.first_extra + n];
        glm::dvec3 sum(0.0);
        for (std::uint32_t c = 0; c < ev.code_count; ++c) {
          sum += sink.position(ids[cases_.extra_codes[ev.first_code + c]]);
        }
        // The centroid, in world coordinates already.
        ids[12 + n] = sink.vertex(sum / double(ev.code_count));
      } else {
        ids[12 + n] = sink.vertex();
      }
      if constexpr (Sink::kStats) ++stats_.centroid_vertices;
    }
    sink.triangles(cases_, entry, ids, i, j, k);
  }

 private:
  /// The case entry of cell (i, j, k): the asymptotic decider settles its ambiguous faces. It
  /// reads only the face's four samples, so the cells on both sides of a face decide alike.
  std::uint32_t entry_index(unsigned config, std::int64_t i, std::int64_t j, std::int64_t k,
                            std::size_t* ambiguous) const {
    const CubeCase& cc = cases_.cases[config];
    unsigned outcome = 0;
    if (cc.ambiguous_count != 0) {
      const float* base = values_ + k * plane_ + j * nx_ + i;
      unsigned bit = 0;
      for (std::size_t f = 0; f < 6; ++f) {
        if (!((cc.ambiguous_faces >> f) & 1)) continue;
        const auto& q = cases_.faces[f].corners;
        const double d0 = double(base[corner_offset_[q[0]]]) - double(iso_);
        const double d1 = double(base[corner_offset_[q[1]]]) - double(iso_);
        const double d2 = double(base[corner_offset_[q[2]]]) - double(iso_);
        const double d3 = double(base[corner_offset_[q[3]]]) - double(iso_);
        // The inside corners are joined across the face when the bilinear saddle is inside:
        // (product of the inside pair) > (product of the outside pair), both pairs shifted by iso.
        const bool q0_inside = ((config >> q[0]) & 1) != 0;
        const double inside_product = q0_inside ? d0 * d2 : d1 * d3;
        const double outside_product = q0_inside ? d1 * d3 : d0 * d2;
        if (inside_product > outside_product) outcome |= 1u << bit;
        ++bit;
      }
      if (ambiguous != nullptr) *ambiguous += bit;
    }
    return cc.first_entry + outcome;
  }

  const float* values_;
  float iso_;
  const CubeCases& cases_;
  ExtractionStats& stats_;
  std::int64_t nx_, plane_;
  std::array<std::int64_t, 8> corner_offset_{};  // sample offset of each cube corner
};

}  // namespace bisturi::surface
