#pragma once
// What the writers refuse to put in a file (the readers would refuse to read it back).

#include <string>

#include "bisturi/scene/oriented_builder.h"

namespace bisturi::mesh_io {

/// Throws InputError naming `file` and the element when the offsets are not a valid CSR, a
/// face is empty, an index is out of range or a coordinate is not finite.
void check_writable(const PolygonMesh& mesh, const std::string& file);

/// The largest number of corners in one face.
std::size_t max_face_size(const PolygonMesh& mesh);

}  // namespace bisturi::mesh_io
