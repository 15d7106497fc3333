#include "ply_header.h"

#include <array>
#include <optional>
#include <utility>

#include "numbers.h"
#include "readers.h"
#include "text_scanner.h"

namespace bisturi::mesh_io {
namespace {

struct TypeName {
  std::string_view name;
  PlyType type;
};

// Both the original PLY names and the sized aliases.
constexpr std::array<TypeName, 16> kTypeNames{{
    {"char", PlyType::Int8},
    {"int8", PlyType::Int8},
    {"uchar", PlyType::Uint8},
    {"uint8", PlyType::Uint8},
    {"short", PlyType::Int16},
    {"int16", PlyType::Int16},
    {"ushort", PlyType::Uint16},
    {"uint16", PlyType::Uint16},
    {"int", PlyType::Int32},
    {"int32", PlyType::Int32},
    {"uint", PlyType::Uint32},
    {"uint32", PlyType::Uint32},
    {"float", PlyType::Float32},
    {"float32", PlyType::Float32},
    {"double", PlyType::Float64},
    {"float64", PlyType::Float64},
}};

std::optional<PlyType> type_from_name(std::string_view name) {
  for (const auto& t : kTypeNames) {
    if (t.name == name) return t.type;
  }
  return std::nullopt;
}

class HeaderParser {
 public:
  HeaderParser(std::string_view file, const ErrorSite& err) : text_(file), err_(err) {}

  PlyHeader parse() {
    if (!text_.next_line() || text_.token() != "ply" || !text_.token().empty()) {
      err_.at_line(1, "not a PLY file (the first line is not 'ply')");
    }
    bool has_format = false;
    for (;;) {
      if (!text_.next_line()) err_.whole("the header has no end_header line (truncated?)");
      const std::string_view keyword = text_.token();
      if (keyword == "end_header") break;
      if (keyword == "format") {
        if (has_format) fail("a second format line");
        read_format();
        has_format = true;
      } else if (keyword == "element") {
        read_element();
      } else if (keyword == "property") {
        read_property();
      } else if (keyword != "comment" && keyword != "obj_info" && !keyword.empty()) {
        skip_unknown_line(keyword);
      }
    }
    if (!has_format) fail("the header has no format line");
    header_.body_offset = text_.next_line_offset();
    header_.body_first_line = text_.line_number() + 1;
    assign_roles();
    return std::move(header_);
  }

 private:
  [[noreturn]] void fail(std::string_view what) const { err_.at_line(text_.line_number(), what); }

  // Old exporters wrote free text into the header without `comment` (Blender 2.4x: "Created by
  // Blender3D 247 - www.blender.org, source file: ..."); rply, assimp and MeshLab skip such
  // lines, so they are skipped here too, with a warning that quotes the line.
  void skip_unknown_line(std::string_view keyword) {
    std::string line(keyword);
    line += text_.rest();
    while (!line.empty() && (line.back() == ' ' || line.back() == '\t' || line.back() == '\r'))
      line.pop_back();
    header_.warnings.push_back(
        cat(err_.file(), ": line ", text_.line_number(),
            ": header line of unknown kind skipped: ", mesh_io::quoted(line)));
  }

  void read_format() {
    const std::string_view encoding = text_.token();
    if (encoding == "ascii") {
      header_.encoding = PlyEncoding::Ascii;
    } else if (encoding == "binary_little_endian") {
      header_.encoding = PlyEncoding::BinaryLittleEndian;
    } else if (encoding == "binary_big_endian") {
      header_.encoding = PlyEncoding::BinaryBigEndian;
    } else {
      fail(cat("unknown PLY format ", quoted(encoding)));
    }
    if (text_.token() != "1.0") fail("unsupported PLY version (expected 1.0)");
  }

  void read_element() {
    PlyElement e;
    e.name = std::string(text_.token());
    const std::string_view count = text_.token();
    const auto n = parse_int(count);
    if (e.name.empty() || !n || *n < 0 || !text_.token().empty()) {
      fail("expected 'element <name> <count>'");
    }
    e.count = static_cast<std::uint64_t>(*n);
    e.header_line = text_.line_number();
    header_.elements.push_back(std::move(e));
  }

  PlyType type_named(std::string_view name) const {
    const auto type = type_from_name(name);
    if (!type) fail(cat("unknown property type ", quoted(name)));
    return *type;
  }

  void read_property() {
    if (header_.elements.empty()) fail("a property before any element");
    std::array<std::string_view, 4> words{};
    std::size_t n = 0;
    for (auto t = text_.token(); !t.empty(); t = text_.token()) {
      if (n == words.size()) fail("too many words in a property line");
      words[n++] = t;
    }
    PlyProperty p;
    if (n > 0 && words[0] == "list") {
      if (n != 4) fail("expected 'property list <count type> <item type> <name>'");
      p.is_list = true;
      p.count_type = type_named(words[1]);
      if (!is_integer(p.count_type)) fail("a list count type must be an integer type");
      p.type = type_named(words[2]);
      p.name = std::string(words[3]);
    } else {
      if (n != 2) fail("expected 'property <type> <name>'");
      p.type = type_named(words[0]);
      p.name = std::string(words[1]);
    }
    header_.elements.back().properties.push_back(std::move(p));
  }

  void assign_roles() {
    bool has_vertex = false, has_face = false;
    for (auto& e : header_.elements) {
      if (e.name == "vertex") {
        if (has_vertex) err_.at_line(e.header_line, "a second vertex element");
        has_vertex = true;
        assign_vertex(e);
      } else if (e.name == "face") {
        if (has_face) err_.at_line(e.header_line, "a second face element");
        has_face = true;
        assign_face(e);
      } else if (e.name == "tristrips") {
        // Its strips are faces in another form; skipping them would lose geometry.
        err_.at_line(e.header_line, "tristrips elements are not supported");
      }
    }
    if (!has_vertex) err_.whole("the PLY header has no vertex element");
  }

  void assign_vertex(PlyElement& e) {
    e.role = PlyElement::Role::Vertex;
    if (e.count > kMaxIndex) {
      err_.at_line(e.header_line, cat(e.count, " vertices: more than 32-bit indices can address"));
    }
    header_.vertex_count = e.count;
    std::array<bool, 3> found{};
    std::array<std::size_t*, 3> slots{&header_.x, &header_.y, &header_.z};
    constexpr std::array<std::string_view, 3> kNames{"x", "y", "z"};
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      for (std::size_t k = 0; k < 3; ++k) {
        if (e.properties[i].name != kNames[k] || found[k]) continue;
        if (e.properties[i].is_list)
          err_.at_line(e.header_line, cat("vertex ", kNames[k], " is a list"));
        *slots[k] = i;
        found[k] = true;
      }
    }
    for (std::size_t k = 0; k < 3; ++k) {
      if (!found[k])
        err_.at_line(e.header_line, cat("the vertex element has no ", kNames[k], " property"));
    }
  }

  void assign_face(PlyElement& e) {
    e.role = PlyElement::Role::Face;
    for (std::size_t i = 0; i < e.properties.size(); ++i) {
      const auto& p = e.properties[i];
      if (p.is_list && (p.name == "vertex_indices" || p.name == "vertex_index")) {
        if (!is_integer(p.type)) {
          err_.at_line(e.header_line,
                       cat("face ", p.name, " has the non-integer item type ", type_name(p.type)));
        }
        header_.face_list = i;
        return;
      }
    }
    err_.at_line(e.header_line, "the face element has no vertex_indices list");
  }

  TextScanner text_;
  const ErrorSite& err_;
  PlyHeader header_;
};

}  // namespace

std::size_t size_of(PlyType t) {
  switch (t) {
    case PlyType::Int8:
    case PlyType::Uint8:
      return 1;
    case PlyType::Int16:
    case PlyType::Uint16:
      return 2;
    case PlyType::Int32:
    case PlyType::Uint32:
    case PlyType::Float32:
      return 4;
    case PlyType::Float64:
      return 8;
  }
  return 0;
}

bool is_integer(PlyType t) {
  return t != PlyType::Float32 && t != PlyType::Float64;
}

std::string_view type_name(PlyType t) {
  for (const auto& n : kTypeNames) {
    if (n.type == t) return n.name;
  }
  return "?";
}

PlyHeader parse_ply_header(std::string_view file, const ErrorSite& err) {
  return HeaderParser(file, err).parse();
}

}  // namespace bisturi::mesh_io
