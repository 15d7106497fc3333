#pragma once
// Internal: the arrays of a new Dlfl, for builders that know the final structure and write every
// record once (marching cubes: one corner per triangle side, twins from the cell tables). The
// result is the same structure the bulk assembler writes for that mesh; validate() checks it.

#include <cstddef>
#include <cstdint>
#include <stdexcept>
#include <utility>

#include "bisturi/scene/dlfl.h"

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

  /// Takes the vertex positions and sizes the other arrays of an empty Dlfl exactly, one rotation
  /// per vertex. Every record is then the caller's to write (the arrays start filled with invalid
  /// handles, labels with 0). Faces get room for face_capacity, so push_face() keeps the view
  /// valid up to that.
  static View size_empty(Dlfl& d, BigVector<Dlfl::Vec3>&& positions, std::size_t corners,
                         std::size_t faces, std::size_t face_capacity, std::size_t edges) {
    if (!d.vertices_.empty() || !d.corners_.empty() || !d.faces_.empty() || !d.edges_.empty()) {
      throw std::logic_error("RawArrays::size_empty: the Dlfl is not empty");
    }
    const std::size_t vertices = positions.size();
    d.positions_ = std::move(positions);
    d.faces_.reserve(face_capacity);
    d.bounding_.reserve(face_capacity);
    d.vertices_.resize(vertices);
    d.rotations_.resize(vertices);
    d.corners_.resize(corners);
    d.faces_.resize(faces);
    d.bounding_.resize(faces);
    d.edges_.resize(edges);
    return {d.corners_.data(),  d.faces_.data(),     d.bounding_.data(), d.edges_.data(),
            d.vertices_.data(), d.rotations_.data(), d.positions_.data()};
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
};

}  // namespace bisturi::construction
