#pragma once
// Marching cubes (marching_cubes.cpp): one vertex per crossed grid edge, made once and shared by
// the (up to four) cells around the edge. Its id is kept by the edge's lower sample: x- and
// y-edges for two sample planes (the slab's lower and upper; plane z in slot z & 1), z-edges for
// one slab. The cells of a slab then look their 12 edges up (cell_ids).

#include <array>
#include <cstddef>
#include <cstdint>

#include "bisturi/scene/big_vector.h"
#include "bisturi/scene/volume/volume.h"
#include "crossing_walks.h"
#include "edge_placement.h"
#include "extraction_sinks.h"
#include "sign_planes.h"

namespace bisturi::surface {

class EdgeVertices {
 public:
  EdgeVertices(const Grid<float>& volume, const EdgePlacement& placement)
      : values_(volume.values.data()),
        placement_(placement),
        nx_(volume.geometry.dims[0]),
        ny_(volume.geometry.dims[1]),
        nz_(volume.geometry.dims[2]),
        plane_(nx_ * ny_) {}

  /// Makes room for the ids, all kNoVertex.
  void allocate() {
    for (auto& v : xid_)
      v.assign(static_cast<std::size_t>(plane_), kNoVertex);
    for (auto& v : yid_)
      v.assign(static_cast<std::size_t>(plane_), kNoVertex);
    zid_.assign(static_cast<std::size_t>(plane_), kNoVertex);
  }

  /// Vertices of the crossed x- and y-edges of sample plane z (classified in `plane`). A sink
  /// that does not place (Sink::kPlaces false) only numbers them.
  template <class Sink>
  void add_plane(std::int64_t z, const SignPlanes::Plane& plane, Sink& sink) {
    std::uint32_t* xid = xid_[static_cast<std::size_t>(z & 1)].data();
    std::uint32_t* yid = yid_[static_cast<std::size_t>(z & 1)].data();
    const float* vz = values_ + z * plane_;
    for_each_plane_crossing(
        plane, [&](int axis, std::int64_t j, std::int64_t w, std::uint64_t cross) {
          const float* v = vz + j * nx_;
          while (cross != 0) {
            const std::int64_t i = 64 * w + __builtin_ctzll(cross);
            cross &= cross - 1;
            if constexpr (!Sink::kPlaces) {
              (axis == 0 ? xid : yid)[j * nx_ + i] = sink.vertex();
            } else if (axis == 0) {
              const double t = placement_.parameter(v + i, 1, i, nx_);
              xid[j * nx_ + i] = sink.vertex(placement_.world(double(i) + t, double(j), double(z)));
            } else {
              const double t = placement_.parameter(v + i, nx_, j, ny_);
              yid[j * nx_ + i] = sink.vertex(placement_.world(double(i), double(j) + t, double(z)));
            }
          }
        });
  }

  /// Vertices of the crossed z-edges between planes k and k + 1.
  template <class Sink>
  void add_slab(std::int64_t k, const SignPlanes::Plane& lower, const SignPlanes::Plane& upper,
                Sink& sink) {
    const float* vk = values_ + k * plane_;
    for_each_slab_crossing(lower, upper, [&](std::int64_t j, std::int64_t w, std::uint64_t cross) {
      const float* v = vk + j * nx_;
      while (cross != 0) {
        const std::int64_t i = 64 * w + __builtin_ctzll(cross);
        cross &= cross - 1;
        std::uint32_t& id = zid_[static_cast<std::size_t>(j * nx_ + i)];
        if constexpr (Sink::kPlaces) {
          const double t = placement_.parameter(v + i, plane_, k, nz_);
          id = sink.vertex(placement_.world(double(i), double(j), double(k) + t));
        } else {
          (void)v;
          id = sink.vertex();
        }
      }
    });
  }

  /// Writes the vertex ids of the 12 cube edges of cell (i, j, k) (cube_cases.h numbering) into
  /// ids[0..11]; the slab k must be the last one added.
  void cell_ids(std::int64_t i, std::int64_t j, std::int64_t k, CellIds& ids) const {
    const std::int64_t x = nx_;
    const std::size_t p0 = static_cast<std::size_t>(k & 1), p1 = 1 - p0;
    const std::uint32_t* x0 = xid_[p0].data() + j * x;
    const std::uint32_t* x1 = xid_[p1].data() + j * x;
    const std::uint32_t* y0 = yid_[p0].data() + j * x;
    const std::uint32_t* y1 = yid_[p1].data() + j * x;
    const std::uint32_t* zz = zid_.data() + j * x;
    ids[0] = x0[i];
    ids[1] = x0[i + x];
    ids[2] = x1[i];
    ids[3] = x1[i + x];
    ids[4] = y0[i];
    ids[5] = y0[i + 1];
    ids[6] = y1[i];
    ids[7] = y1[i + 1];
    ids[8] = zz[i];
    ids[9] = zz[i + 1];
    ids[10] = zz[i + x];
    ids[11] = zz[i + x + 1];
  }

 private:
  const float* values_;
  const EdgePlacement& placement_;
  std::int64_t nx_, ny_, nz_, plane_;
  std::array<ScratchVector<std::uint32_t>, 2> xid_, yid_;
  ScratchVector<std::uint32_t> zid_;
};

}  // namespace bisturi::surface
