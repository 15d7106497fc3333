// STL, ascii or binary, as a triangle soup: every facet brings its own positions.
//
// Telling them apart: a file whose size is exactly 84 + 50 n, n being the count at byte 80, is
// binary even when its header starts with "solid" (many exporters write that). An ascii file
// cannot match by chance below 7.5 GB: its count bytes are text (each >= 0x09), so n >= 151M.

#include <cmath>
#include <cstdint>

#include "byte_order.h"
#include "numbers.h"
#include "parse_errors.h"
#include "progress.h"
#include "readers.h"
#include "text_scanner.h"

namespace bisturi::mesh_io {
namespace {

constexpr std::size_t kHeaderBytes = 84;
constexpr std::size_t kTriangleBytes = 50;

bool equals_nocase(std::string_view a, std::string_view b) {
  if (a.size() != b.size()) return false;
  for (std::size_t i = 0; i < a.size(); ++i) {
    const char c = a[i] >= 'A' && a[i] <= 'Z' ? static_cast<char>(a[i] - 'A' + 'a') : a[i];
    if (c != b[i]) return false;
  }
  return true;
}

bool starts_with_solid(std::string_view text) {
  const std::size_t start = text.find_first_not_of(" \t\r\n");
  return start != std::string_view::npos && equals_nocase(text.substr(start, 5), "solid");
}

// Binary data (floats, the count) shows control bytes that text does not hold.
bool looks_binary(std::string_view head) {
  for (const char ch : head) {
    const auto c = static_cast<unsigned char>(ch);
    if (c < 0x09 || (c > 0x0d && c < 0x20)) return true;
  }
  return false;
}

void read_binary(std::span<const std::byte> data, const ErrorSite& err, PolygonMesh& mesh,
                 ProgressTicker& progress) {
  if (data.size() < kHeaderBytes) {
    err.at_byte(data.size(),
                cat("binary STL: file ends inside the 84-byte header (", data.size(), " bytes)"));
  }
  const std::uint32_t count = load<std::uint32_t>(data.data() + 80, swap_for(true));
  const std::uint64_t expected = kHeaderBytes + std::uint64_t{count} * kTriangleBytes;
  if (expected != data.size()) {
    err.at_byte(80,
                cat("binary STL: ", count, " triangles need ", expected, " bytes, the file has ",
                    data.size(), expected > data.size() ? " (truncated?)" : ""));
  }
  if (std::uint64_t{count} * 3 > kMaxIndex)
    err.at_byte(80, "more triangles than fit 32-bit indices");
  mesh.positions.reserve(std::size_t{count} * 3);
  mesh.indices.reserve(std::size_t{count} * 3);
  mesh.offsets.reserve(std::size_t{count} + 1);
  for (std::uint32_t t = 0; t < count; ++t) {
    // Skip the facet normal: the vertex order carries the orientation.
    const std::size_t record = kHeaderBytes + std::size_t{t} * kTriangleBytes;
    progress.at(record);
    for (std::size_t k = 0; k < 3; ++k) {
      Dlfl::Vec3 p;
      for (int a = 0; a < 3; ++a) {
        const std::size_t at = record + 12 + 12 * k + 4 * static_cast<std::size_t>(a);
        p[a] = load<float>(data.data() + at, swap_for(true));
        if (!std::isfinite(p[a])) {
          err.at_byte(at, cat("triangle ", t, ": vertex ", k, ": coordinate is not finite"));
        }
      }
      mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
      mesh.positions.push_back(p);
    }
    mesh.offsets.push_back(static_cast<std::uint32_t>(mesh.indices.size()));
  }
}

class AsciiStlReader {
 public:
  AsciiStlReader(std::string_view text, const ErrorSite& err) : text_(text), err_(err) {}

  void read(PolygonMesh& mesh, ProgressTicker& progress) {
    expect("solid");
    text_.next_line();  // past the solid's name
    for (;;) {
      progress.at(text_.line_offset());
      const std::string_view word = next("'facet' or 'endsolid'");
      if (equals_nocase(word, "facet")) {
        facet(mesh);
      } else if (equals_nocase(word, "endsolid")) {
        // Several solids may follow one another.
        text_.next_line();
        const std::string_view more = text_.token_across_lines();
        if (more.empty()) return;
        if (!equals_nocase(more, "solid"))
          fail(cat("expected 'solid' or the end, found ", quoted(more)));
        text_.next_line();
      } else {
        fail(cat("expected 'facet' or 'endsolid', found ", quoted(word)));
      }
    }
  }

 private:
  [[noreturn]] void fail(std::string_view what) const { err_.at_line(text_.line_number(), what); }

  std::string_view next(std::string_view expected) {
    const std::string_view t = text_.token_across_lines();
    if (t.empty()) fail(cat("the file ends where ", expected, " was expected (truncated?)"));
    return t;
  }

  void expect(std::string_view keyword) {
    const std::string_view t = next(cat("'", keyword, "'"));
    if (!equals_nocase(t, keyword)) fail(cat("expected '", keyword, "', found ", quoted(t)));
  }

  void facet(PolygonMesh& mesh) {
    const std::size_t f = mesh.face_count();
    expect("normal");
    for (int k = 0; k < 3; ++k)
      next("a normal coordinate");  // not used, as in binary files
    expect("outer");
    expect("loop");
    std::size_t corners = 0;
    for (;;) {
      const std::string_view word = next("'vertex' or 'endloop'");
      if (equals_nocase(word, "endloop")) break;
      if (!equals_nocase(word, "vertex")) {
        fail(cat("facet ", f, ": expected 'vertex' or 'endloop', found ", quoted(word)));
      }
      Dlfl::Vec3 p;
      for (int a = 0; a < 3; ++a) {
        const std::string_view t = next("a vertex coordinate");
        const auto v = parse_double(t);
        if (!v) fail(cat("facet ", f, ": vertex ", corners, ": bad coordinate ", quoted(t)));
        if (!std::isfinite(*v)) {
          fail(
              cat("facet ", f, ": vertex ", corners, ": coordinate ", quoted(t), " is not finite"));
        }
        p[a] = *v;
      }
      if (mesh.positions.size() == kMaxIndex) fail("more vertices than 32-bit indices can address");
      mesh.indices.push_back(static_cast<std::uint32_t>(mesh.positions.size()));
      mesh.positions.push_back(p);
      ++corners;
    }
    if (corners == 0) fail(cat("facet ", f, ": no vertex"));
    if (!close_face(mesh)) fail("more face corners than 32-bit offsets can address");
    expect("endfacet");
  }

  TextScanner text_;
  const ErrorSite& err_;
};

}  // namespace

MeshFile read_stl(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options) {
  const ErrorSite err(name);
  if (data.empty()) err.whole("file is empty");
  MeshFile out;
  out.format = MeshFormat::Stl;
  out.has_vertex_list = false;
  out.source_bytes = data.size();
  ProgressTicker progress(options, data.size());

  const std::string_view text = as_text(data);
  bool binary = true;
  if (data.size() >= kHeaderBytes) {
    const std::uint32_t count = load<std::uint32_t>(data.data() + 80, swap_for(true));
    const bool size_matches = kHeaderBytes + std::uint64_t{count} * kTriangleBytes == data.size();
    binary = size_matches || !starts_with_solid(text) || looks_binary(text.substr(0, 512));
  } else {
    binary = !starts_with_solid(text);
  }
  if (binary) {
    read_binary(data, err, out.polygons, progress);
  } else {
    AsciiStlReader(text, err).read(out.polygons, progress);
  }
  progress.finish();
  return out;
}

}  // namespace bisturi::mesh_io
