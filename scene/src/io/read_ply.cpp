// PLY (ascii, binary_little_endian, binary_big_endian): the vertex element's x, y, z and the face
// element's vertex_indices (or vertex_index) list; every other property and element is skipped
// by its declared layout.

#include <algorithm>
#include <cmath>
#include <utility>

#include "ply_header.h"
#include "ply_sources.h"
#include "progress.h"
#include "readers.h"

namespace bisturi::mesh_io {
namespace {

/// Fails when the element counts of the header need more data than follows it: the smallest
/// record (empty lists, one index per face) times the count, summed over the elements.
void check_counts(const PlyHeader& h, std::size_t available, const ErrorSite& err) {
  const bool binary = h.encoding != PlyEncoding::Ascii;
  // Ascii: n values take at least 2n - 1 bytes (one character and one separator each).
  const std::uint64_t budget = binary ? available : (std::uint64_t{available} + 1) / 2;
  std::uint64_t used = 0;
  for (const auto& e : h.elements) {
    std::uint64_t record = 0;
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      const auto& p = e.properties[i];
      const bool face_list = e.role == PlyElement::Role::Face && i == h.face_list;
      if (binary) {
        record +=
            p.is_list ? size_of(p.count_type) + (face_list ? size_of(p.type) : 0) : size_of(p.type);
      } else {
        record += face_list ? 2 : 1;
      }
    }
    if (record == 0) continue;
    if ((budget - used) / record < e.count) {
      const std::string what =
          cat("element ", e.name, " ", e.count, ": the data ends before that many records (",
              e.count, " of at least ", record, binary ? " bytes" : " values", " each; ", available,
              " bytes follow the header)");
      if (binary) err.at_byte(h.body_offset, what);
      err.at_line(e.header_line, what);
    }
    used += e.count * record;
  }
}

template <class Source>
class BodyReader {
 public:
  BodyReader(Source& source, const PlyHeader& header, PolygonMesh& mesh, ProgressTicker& progress)
      : src_(source), h_(header), mesh_(mesh), progress_(progress) {}

  void read() {
    for (const auto& e : h_.elements) {
      switch (e.role) {
        case PlyElement::Role::Vertex:
          vertices(e);
          break;
        case PlyElement::Role::Face:
          faces(e);
          break;
        case PlyElement::Role::Skip:
          skip(e);
          break;
      }
    }
    src_.finish();
  }

 private:
  void skip_list(const PlyProperty& p) {
    const std::int64_t n = src_.integer(p.count_type);
    if (n < 0) src_.fail(cat("negative list length ", n));
    src_.skip_items(p.type, static_cast<std::uint64_t>(n));
  }

  void skip_value(const PlyProperty& p) {
    if (p.is_list) {
      skip_list(p);
    } else {
      src_.skip(p.type);
    }
  }

  void skip(const PlyElement& e) {
    if (e.properties.empty() || src_.skip_fixed(e)) return;
    for (std::uint64_t i = 0; i < e.count; ++i) {
      src_.begin(e, i);
      progress_.at(src_.position());
      for (const auto& p : e.properties)
        skip_value(p);
    }
  }

  void vertices(const PlyElement& e) {
    mesh_.positions.reserve(static_cast<std::size_t>(e.count));
    for (std::uint64_t i = 0; i < e.count; ++i) {
      src_.begin(e, i);
      progress_.at(src_.position());
      Dlfl::Vec3 p;
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        const auto& prop = e.properties[k];
        const int axis = k == h_.x ? 0 : k == h_.y ? 1 : k == h_.z ? 2 : -1;
        if (axis < 0) {
          skip_value(prop);
          continue;
        }
        p[axis] = src_.real(prop.type);
        if (!std::isfinite(p[axis])) src_.fail(cat("coordinate ", prop.name, " is not finite"));
      }
      mesh_.positions.push_back(p);
    }
  }

  void faces(const PlyElement& e) {
    mesh_.offsets.reserve(static_cast<std::size_t>(e.count) + 1);
    mesh_.indices.reserve(static_cast<std::size_t>(e.count) * 3);
    for (std::uint64_t i = 0; i < e.count; ++i) {
      src_.begin(e, i);
      progress_.at(src_.position());
      for (std::size_t k = 0; k < e.properties.size(); ++k) {
        if (k == h_.face_list) {
          face_indices(e.properties[k]);
        } else {
          skip_value(e.properties[k]);
        }
      }
    }
  }

  void face_indices(const PlyProperty& p) {
    const std::int64_t n = src_.integer(p.count_type);
    if (n <= 0)
      src_.fail(n == 0 ? std::string("no vertex index") : cat("negative list length ", n));
    src_.expect_items(p.type, static_cast<std::uint64_t>(n));
    for (std::int64_t j = 0; j < n; ++j) {
      const std::int64_t v = src_.integer(p.type);
      if (v < 0 || static_cast<std::uint64_t>(v) >= h_.vertex_count) {
        src_.fail(cat("vertex index ", v, " out of range (", h_.vertex_count, " vertices)"));
      }
      mesh_.indices.push_back(static_cast<std::uint32_t>(v));
    }
    if (!close_face(mesh_)) src_.fail("more face corners than 32-bit offsets can address");
  }

  Source& src_;
  const PlyHeader& h_;
  PolygonMesh& mesh_;
  ProgressTicker& progress_;
};

}  // namespace

MeshFile read_ply(std::span<const std::byte> data, const std::string& name,
                  const ReadOptions& options) {
  const ErrorSite err(name);
  if (data.empty()) err.whole("file is empty");
  PlyHeader header = parse_ply_header(as_text(data), err);
  check_counts(header, data.size() - header.body_offset, err);

  MeshFile out;
  out.format = MeshFormat::Ply;
  out.source_bytes = data.size();
  ProgressTicker progress(options, data.size());
  if (header.encoding == PlyEncoding::Ascii) {
    PlyAsciiSource source(as_text(data).substr(header.body_offset), header.body_offset,
                          header.body_first_line, err);
    BodyReader(source, header, out.polygons, progress).read();
  } else {
    const bool little = header.encoding == PlyEncoding::BinaryLittleEndian;
    PlyBinarySource source(data, header.body_offset, swap_for(little), err);
    BodyReader(source, header, out.polygons, progress).read();
  }
  progress.finish();
  out.warnings = std::move(header.warnings);
  return out;
}

}  // namespace bisturi::mesh_io
