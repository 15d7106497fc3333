#pragma once
// Internal: the arrays of a new Dlfl, for builders that know the final structure and write every
// record once (marching cubes: one corner per triangle side, twins from the cell tables). The
// result is the same structure the bulk assembler writes for that mesh; validate() checks it.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>

#include "bisturi/scene/dlfl.h"
#include "prefault.h"

namespace bisturi::construction {

class RawArrays {
 public:
  struct View {
    Dlfl::CornerRecord* corners = nullptr;
    Dlfl::FaceRecord* faces = nullptr;
    std::uint8_t* bounding = nullptr;
    CornerPair* edges = nullptr;
    Dlfl::VertexRecord* vertices = nullptr;
    Dlfl::RotationRecord* rotations = nullptr;
    Dlfl::Vec3* positions = nullptr;
  };

  /// Takes the vertex positions and sizes the other arrays of an empty Dlfl exactly (their room
  /// rounded up to whole huge pages where that adds at most a sixteenth), one rotation per
  /// vertex. Every record is then the caller's to write (the arrays start filled with invalid
  /// handles, labels with 0). Faces get room for face_capacity, so push_face() keeps the view
  /// valid up to that.
  static View size_empty(Dlfl& d, BigVector<Dlfl::Vec3>&& positions, std::size_t corners,
                         std::size_t faces, std::size_t face_capacity, std::size_t edges) {
    if (!d.vertices_.empty() || !d.corners_.empty() || !d.faces_.empty() || !d.edges_.empty()) {
      throw std::logic_error("RawArrays::size_empty: the Dlfl is not empty");
    }
    const std::size_t vertices = positions.size();
    d.positions_ = std::move(positions);
    // Mapped before the fill: one system call per array instead of a fault per page.
    reserve_whole(d.faces_, face_capacity);
    reserve_whole(d.bounding_, face_capacity);
    reserve_whole(d.vertices_, vertices);
    reserve_whole(d.rotations_, vertices);
    reserve_whole(d.corners_, corners);
    reserve_whole(d.edges_, edges);
    d.vertices_.resize(vertices);
    d.rotations_.resize(vertices);
    d.corners_.resize(corners);
    d.faces_.resize(faces);
    d.bounding_.resize(faces);
    d.edges_.resize(edges);
    return view(d);
  }

  /// Resizes the corner and edge arrays of a sized Dlfl (new records invalid, the old ones
  /// kept) to exactly these sizes; the view then points at the new arrays.
  static View grow(Dlfl& d, std::size_t corners, std::size_t edges) {
    grow_to(d.corners_, corners);
    grow_to(d.edges_, edges);
    return view(d);
  }

  /// Resizes the face arrays (records and labels) to exactly n faces.
  static View grow_faces(Dlfl& d, std::size_t n) {
    grow_to(d.faces_, n);
    grow_to(d.bounding_, n);
    return view(d);
  }

  /// Appends a face (its corners' face fields are the caller's to set).
  static FaceId push_face(Dlfl& d, CornerId first, bool bounding) {
    const FaceId f(static_cast<std::uint32_t>(d.faces_.size()));
    d.faces_.push_back({first});
    d.bounding_.push_back(bounding ? 1 : 0);
    return f;
  }

  /// After the records are written: attribute arrays follow the sizes, caches see a new topology
  /// (`topology_changes`: the version steps of the operator calls the writer stands for).
  static void finish(Dlfl& d, std::uint64_t topology_changes = 1) {
    d.vertex_props_.resize(d.vertices_.size());
    d.corner_props_.resize(d.corners_.size());
    d.face_props_.resize(d.faces_.size());
    d.edge_props_.resize(d.edges_.size());
    d.topology_version_ += topology_changes;
  }

 private:
  static View view(Dlfl& d) {
    return {d.corners_.data(),  d.faces_.data(),     d.bounding_.data(), d.edges_.data(),
            d.vertices_.data(), d.rotations_.data(), d.positions_.data()};
  }

  /// Room for n records (whole huge pages where cheap), the first n mapped for writing.
  template <class T>
  static void reserve_whole(BigVector<T>& v, std::size_t n) {
    v.reserve(whole_huge_pages(n, sizeof(T)));
    prefault(v.data(), n * sizeof(T));
  }

  /// Resizes to n; a new block holds exactly n (whole huge pages where cheap), not double.
  template <class T>
  static void grow_to(BigVector<T>& v, std::size_t n) {
    if (v.capacity() < n) {
      BigVector<T> bigger;
      reserve_whole(bigger, n);
      bigger.assign(v.begin(), v.end());
      v = std::move(bigger);
    }
    v.resize(n);
  }
};

}  // namespace bisturi::construction
