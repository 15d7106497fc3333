// Wavefront OBJ: `v` and `f` statements; everything else (vt, vn, g, o, s, usemtl, mtllib, l,
// p, free-form geometry) carries nothing a polygon list keeps and is skipped.
//
// Written here rather than with Debian's tinyobjloader (2.0.0rc10, checked on this data): it
// reads a malformed coordinate (`v 1 abc 2`) or a missing one as 0 and NaN as 0 without a
// word, reports an out-of-range index only as one warning for the whole file (and passes a
// negative one below the first vertex through as a negative index), names no reason for a bad
// face, and its own decimal parser does not give the same double back for most 17-digit values.

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

bool is_letter(char c) {
  return (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z');
}

struct StatementCounts {
  std::size_t vertices = 0;
  std::size_t faces = 0;
};

// A quick pass over the line starts, so that the arrays are allocated once (OBJ has no counts).
// Each line holds at least two bytes, so the counts are bounded by the file size.
StatementCounts count_statements(std::string_view text) {
  StatementCounts n;
  for (std::size_t pos = 0; pos < text.size();) {
    while (pos < text.size() && (text[pos] == ' ' || text[pos] == '\t'))
      ++pos;
    if (pos + 1 < text.size() && (text[pos + 1] == ' ' || text[pos + 1] == '\t')) {
      if (text[pos] == 'v') ++n.vertices;
      if (text[pos] == 'f') ++n.faces;
    }
    const std::size_t nl = text.find('\n', pos);
    pos = nl == std::string_view::npos ? text.size() : nl + 1;
  }
  return n;
}

class ObjReader {
 public:
  ObjReader(std::string_view text, const std::string& name)
      : text_(text, {.comment = '#', .backslash_continues = true}), err_(name) {}

  void read(PolygonMesh& mesh, ProgressTicker& progress, StatementCounts expected) {
    mesh.positions.reserve(expected.vertices);
    mesh.offsets.reserve(expected.faces + 1);
    mesh.indices.reserve(expected.faces * 3);
    while (text_.next_line()) {
      progress.at(text_.line_offset());
      const std::string_view keyword = text_.token();
      if (keyword.empty()) continue;
      if (keyword == "v") {
        read_vertex(mesh);
      } else if (keyword == "f" || keyword == "fo") {
        read_face(mesh);
      } else if (!is_letter(keyword[0])) {
        fail(cat("not an OBJ statement: ", quoted(keyword)));
      }
    }
    // Positive indices may name vertices defined later in the file; the largest one decides.
    if (forward_.index > mesh.positions.size()) {
      err_.at_line(forward_.line, cat("face ", forward_.face, ": vertex index ", forward_.index,
                                      " out of range (", mesh.positions.size(), " vertices)"));
    }
    if (mesh.positions.empty()) err_.whole("no vertex (`v`) statement: not an OBJ mesh");
  }

 private:
  struct ForwardIndex {
    std::uint64_t index = 0;
    std::size_t line = 0;
    std::size_t face = 0;
  };

  [[noreturn]] void fail(std::string_view what) const { err_.at_line(text_.line_number(), what); }

  void read_vertex(PolygonMesh& mesh) {
    const std::size_t v = mesh.positions.size();
    if (v == kMaxIndex) fail("more vertices than 32-bit indices can address");
    const Dlfl::Vec3 p = read_coordinates(text_, err_, v);
    // A w coordinate or vertex colours may follow; neither is a position.
    mesh.positions.push_back(p);
  }

  void read_face(PolygonMesh& mesh) {
    const std::size_t f = mesh.face_count();
    const std::uint64_t n = mesh.positions.size();
    std::size_t corners = 0;
    for (std::string_view t = text_.token(); !t.empty(); t = text_.token(), ++corners) {
      // v, v/vt, v//vn or v/vt/vn: the vertex index is what precedes the first slash.
      const std::string_view vertex = t.substr(0, t.find('/'));
      const auto index = parse_int(vertex);
      if (!index) fail(cat("face ", f, ": bad vertex index ", quoted(t)));
      std::uint64_t resolved = 0;
      if (*index > 0) {
        resolved = static_cast<std::uint64_t>(*index) - 1;
        if (resolved >= kMaxIndex) {
          fail(cat("face ", f, ": vertex index ", *index, " out of range (", n, " vertices)"));
        }
        if (resolved >= n && resolved + 1 > forward_.index) {
          forward_ = {resolved + 1, text_.line_number(), f};
        }
      } else if (*index < 0 && static_cast<std::uint64_t>(-(*index + 1)) < n) {
        resolved = n - static_cast<std::uint64_t>(-(*index + 1)) - 1;
      } else if (*index < 0) {
        fail(cat("face ", f, ": vertex index ", *index, " out of range (", n, " vertices)"));
      } else {
        fail(cat("face ", f, ": vertex index 0 (OBJ indices start at 1)"));
      }
      mesh.indices.push_back(static_cast<std::uint32_t>(resolved));
    }
    if (corners == 0) fail(cat("face ", f, ": no vertex index"));
    if (!close_face(mesh)) fail("more face corners than 32-bit offsets can address");
  }

  TextScanner text_;
  ErrorSite err_;
  ForwardIndex forward_;
};

}  // namespace

MeshFile read_obj(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options) {
  if (data.empty()) ErrorSite(name).whole("file is empty");
  MeshFile out;
  out.format = MeshFormat::Obj;
  out.source_bytes = data.size();
  ProgressTicker progress(options, data.size());
  ObjReader(as_text(data), name).read(out.polygons, progress, count_statements(as_text(data)));
  progress.finish();
  return out;
}

}  // namespace bisturi::mesh_io
