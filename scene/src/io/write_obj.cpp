#include <charconv>

#include "bisturi/scene/io/mesh_file.h"
#include "file_io.h"
#include "mesh_check.h"

namespace bisturi {
namespace {

// Shortest decimal that reads back as the same double (std::to_chars without a precision): exact
// like %.17g, and shorter for most values.
void append_number(std::string& line, double v) {
  char buf[32];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  line.append(buf, r.ptr);
}

void append_number(std::string& line, std::uint64_t v) {
  char buf[24];
  const auto r = std::to_chars(buf, buf + sizeof buf, v);
  line.append(buf, r.ptr);
}

}  // namespace

void write_obj(const std::filesystem::path& file, const PolygonMesh& mesh) {
  const std::string name = file.string();
  mesh_io::check_writable(mesh, name);
  mesh_io::FileWriter out(file);
  out.write("# written by bisturi\n");
  std::string line;
  for (const auto& p : mesh.positions) {
    line.clear();
    line += "v ";
    append_number(line, p.x);
    line += ' ';
    append_number(line, p.y);
    line += ' ';
    append_number(line, p.z);
    line += '\n';
    out.write(line);
  }
  for (std::size_t f = 0; f < mesh.face_count(); ++f) {
    line.clear();
    line += 'f';
    for (const std::uint32_t i : mesh.face(f)) {
      line += ' ';
      append_number(line, std::uint64_t{i} + 1);
    }
    line += '\n';
    out.write(line);
  }
  out.close();
}

}  // namespace bisturi
