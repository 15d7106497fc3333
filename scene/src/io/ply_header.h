#pragma once
// The header of a PLY file: encoding and element layout, checked for what the body reader
// needs (a vertex element with scalar x, y, z; a face element with an integer index list).

#include <cstddef>
#include <cstdint>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/scene/io/mesh_file.h"
#include "parse_errors.h"

namespace bisturi::mesh_io {

enum class PlyType : std::uint8_t { Int8, Uint8, Int16, Uint16, Int32, Uint32, Float32, Float64 };

std::size_t size_of(PlyType t);
bool is_integer(PlyType t);
std::string_view type_name(PlyType t);

struct PlyProperty {
  std::string name;
  PlyType type = PlyType::Uint8;  ///< the value type, or the item type of a list
  bool is_list = false;
  PlyType count_type = PlyType::Uint8;
};

struct PlyElement {
  enum class Role : std::uint8_t { Skip, Vertex, Face };
  std::string name;
  std::uint64_t count = 0;
  std::vector<PlyProperty> properties;
  Role role = Role::Skip;
  std::size_t header_line = 0;
};

struct PlyHeader {
  PlyEncoding encoding = PlyEncoding::Ascii;
  std::vector<PlyElement> elements;
  std::size_t body_offset = 0;      ///< first byte after the end_header line
  std::size_t body_first_line = 0;  ///< its line number (ascii bodies)
  std::uint64_t vertex_count = 0;
  std::size_t x = 0, y = 0, z = 0;    ///< vertex property positions
  std::size_t face_list = 0;          ///< face property position of vertex_indices
  std::vector<std::string> warnings;  ///< header lines skipped, each with the file and line
};

PlyHeader parse_ply_header(std::string_view file, const ErrorSite& err);

}  // namespace bisturi::mesh_io
