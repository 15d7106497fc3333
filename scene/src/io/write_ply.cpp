#include <charconv>
#include <cstdint>
#include <limits>

#include "bisturi/scene/io/mesh_file.h"
#include "byte_order.h"
#include "file_io.h"
#include "mesh_check.h"
#include "parse_errors.h"

namespace bisturi {
namespace {

struct FaceLayout {
  bool wide_count;    // uint instead of uchar
  bool wide_indices;  // uint instead of int
};

std::string header(const PolygonMesh& mesh, PlyEncoding encoding, FaceLayout layout) {
  const char* format = encoding == PlyEncoding::Ascii                ? "ascii"
                       : encoding == PlyEncoding::BinaryLittleEndian ? "binary_little_endian"
                                                                     : "binary_big_endian";
  return mesh_io::cat("ply\nformat ", format, " 1.0\ncomment written by bisturi\nelement vertex ",
                      mesh.positions.size(),
                      "\nproperty double x\nproperty double y\nproperty double z\nelement face ",
                      mesh.face_count(), "\nproperty list ", layout.wide_count ? "uint" : "uchar",
                      " ", layout.wide_indices ? "uint" : "int", " vertex_indices\nend_header\n");
}

template <class T>
void append_text(std::string& s, T v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  s.append(buf, r.ptr);
}

void write_ascii(mesh_io::FileWriter& out, const PolygonMesh& mesh) {
  std::string line;
  for (const auto& p : mesh.positions) {
    line.clear();
    append_text(line, p.x);
    line += ' ';
    append_text(line, p.y);
    line += ' ';
    append_text(line, p.z);
    line += '\n';
    out.write(line);
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    line.clear();
    append_text(line, mesh.face(f).size());
    for (const std::uint32_t i : mesh.face(f)) {
      line += ' ';
      append_text(line, i);
    }
    line += '\n';
    out.write(line);
  }
}

template <class T>
void append_binary(std::string& s, T v, bool swap) {
  std::byte b[sizeof(T)];
  mesh_io::store(b, v, swap);
  s.append(reinterpret_cast<const char*>(b), sizeof(T));
}

void write_binary(mesh_io::FileWriter& out, const PolygonMesh& mesh, bool swap, FaceLayout layout) {
  std::string record;
  for (const auto& p : mesh.positions) {
    record.clear();
    append_binary(record, p.x, swap);
    append_binary(record, p.y, swap);
    append_binary(record, p.z, swap);
    out.write(record);
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    const auto face = mesh.face(f);
    record.clear();
    if (layout.wide_count) {
      append_binary(record, static_cast<std::uint32_t>(face.size()), swap);
    } else {
      append_binary(record, static_cast<std::uint8_t>(face.size()), swap);
    }
    // uint32 indices below 2^31 have the same bytes as int32 ones.
    for (const std::uint32_t i : face)
      append_binary(record, i, swap);
    out.write(record);
  }
}

}  // namespace

void write_ply(const std::filesystem::path& file, const PolygonMesh& mesh, PlyEncoding encoding) {
  mesh_io::check_writable(mesh, file.string());
  const FaceLayout layout{
      mesh_io::max_face_size(mesh) > std::numeric_limits<std::uint8_t>::max(),
      mesh.positions.size() > static_cast<std::size_t>(std::numeric_limits<std::int32_t>::max())};
  mesh_io::FileWriter out(file);
  out.write(header(mesh, encoding, layout));
  if (encoding == PlyEncoding::Ascii) {
    write_ascii(out, mesh);
  } else {
    write_binary(out, mesh, mesh_io::swap_for(encoding == PlyEncoding::BinaryLittleEndian), layout);
  }
  out.close();
}

}  // namespace bisturi
