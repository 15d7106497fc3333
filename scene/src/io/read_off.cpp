// OFF (Object File Format): "OFF" (or COFF, NOFF, CNOFF, STOFF...), the counts "V F E", V
// vertex lines, F face lines "n i1 ... in". What follows the three coordinates of a vertex line
// (normals, colours, texture coordinates) and the n indices of a face line (a colour) is
// ignored; for that reason each vertex and face must sit on its own line. '#' starts a comment.

#include <cmath>
#include <cstdint>

#include "numbers.h"
#include "parse_errors.h"
#include "progress.h"
#include "read_coordinates.h"
#include "readers.h"
#include "text_scanner.h"

namespace bisturi::mesh_io {
namespace {

class OffReader {
 public:
  OffReader(std::string_view text, const ErrorSite& err)
      : text_(text, {.comment = '#'}), err_(err), size_(text.size()) {}

  void read(PolygonMesh& mesh, ProgressTicker& progress) {
    header();
    mesh.positions.reserve(static_cast<std::size_t>(vertices_));
    mesh.offsets.reserve(static_cast<std::size_t>(faces_) + 1);
    for (std::uint64_t v = 0; v < vertices_; ++v) {
      next_data_line(cat("vertex ", v));
      progress.at(text_.line_offset());
      mesh.positions.push_back(vertex(v));
    }
    for (std::uint64_t f = 0; f < faces_; ++f) {
      next_data_line(cat("face ", f));
      progress.at(text_.line_offset());
      face(mesh, f);
    }
    if (next_data_line_or_end()) fail("data after the last face");
  }

 private:
  [[noreturn]] void fail(std::string_view what) const { err_.at_line(text_.line_number(), what); }

  bool next_data_line_or_end() {
    while (text_.next_line()) {
      if (text_.rest().find_first_not_of(" \t\r\v\f") != std::string_view::npos) return true;
    }
    return false;
  }

  void next_data_line(const std::string& what) {
    if (!next_data_line_or_end()) fail(cat("the file ends before ", what, " (truncated?)"));
  }

  void header() {
    if (!next_data_line_or_end()) err_.whole("file is empty");
    const std::string_view keyword = text_.token();
    if (keyword.size() < 3 || keyword.substr(keyword.size() - 3) != "OFF" ||
        keyword.substr(0, keyword.size() - 3).find_first_not_of("STCN") != std::string_view::npos) {
      fail(cat("not an OFF file: the first word is ", quoted(keyword)));
    }
    std::string_view count = text_.token();
    if (count == "BINARY") fail("binary OFF is not supported");
    if (count.empty()) {  // the counts may share the keyword's line
      next_data_line("the counts line");
      count = text_.token();
    }
    vertices_ = count_value(count, "vertex");
    faces_ = count_value(text_.token(), "face");
    // An edge count may follow; it is not used.
    if (vertices_ > kMaxIndex)
      fail(cat(vertices_, " vertices: more than 32-bit indices can address"));
    // Each vertex line holds at least 5 bytes ("0 0 0"), each face line at least 3 ("1 0").
    const std::size_t left = size_ - text_.next_line_offset();
    if (vertices_ > left / 5 || faces_ > (left - vertices_ * 5) / 3) {
      fail(cat("the header declares ", vertices_, " vertices and ", faces_, " faces, but only ",
               left, " bytes follow (truncated?)"));
    }
  }

  std::uint64_t count_value(std::string_view token, std::string_view what) const {
    const auto n = parse_int(token);
    if (!n || *n < 0) fail(cat("bad ", what, " count ", quoted(token)));
    return static_cast<std::uint64_t>(*n);
  }

  Dlfl::Vec3 vertex(std::uint64_t v) { return read_coordinates(text_, err_, v); }

  void face(PolygonMesh& mesh, std::uint64_t f) {
    const std::string_view count = text_.token();
    const auto n = parse_int(count);
    if (!n || *n < 0) fail(cat("face ", f, ": bad index count ", quoted(count)));
    if (*n == 0) fail(cat("face ", f, ": no vertex index"));
    for (std::int64_t k = 0; k < *n; ++k) {
      const std::string_view t = text_.token();
      if (t.empty()) fail(cat("face ", f, ": ", *n, " indices declared, ", k, " found"));
      const auto index = parse_int(t);
      if (!index) fail(cat("face ", f, ": bad vertex index ", quoted(t)));
      if (*index < 0 || static_cast<std::uint64_t>(*index) >= vertices_) {
        fail(
            cat("face ", f, ": vertex index ", *index, " out of range (", vertices_, " vertices)"));
      }
      mesh.indices.push_back(static_cast<std::uint32_t>(*index));
    }
    if (!close_face(mesh)) fail("more face corners than 32-bit offsets can address");
  }

  TextScanner text_;
  const ErrorSite& err_;
  std::size_t size_;
  std::uint64_t vertices_ = 0;
  std::uint64_t faces_ = 0;
};

}  // namespace

MeshFile read_off(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options) {
  const ErrorSite err(name);
  if (data.empty()) err.whole("file is empty");
  MeshFile out;
  out.format = MeshFormat::Off;
  out.source_bytes = data.size();
  ProgressTicker progress(options, data.size());
  OffReader(as_text(data), err).read(out.polygons, progress);
  progress.finish();
  return out;
}

}  // namespace bisturi::mesh_io
