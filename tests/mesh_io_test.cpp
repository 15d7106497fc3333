// Mesh file readers and writers: each format read exactly (positions to the bit, polygons in file
// order), written files read back unchanged, and bad input refused with an InputError naming the
// file, the line or byte, and the element.

#include <gtest/gtest.h>

#include <unistd.h>
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <limits>
#include <random>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/io/mesh_file.h"

namespace bisturi {
namespace {

using Faces = std::vector<std::vector<std::uint32_t>>;

std::span<const std::byte> bytes_of(std::string_view s) {
  return {reinterpret_cast<const std::byte*>(s.data()), s.size()};
}

MeshFile read_text(std::string_view data, MeshFormat format, const std::string& name = "mesh") {
  return read_mesh_from_memory(bytes_of(data), format, name);
}

Faces faces_of(const PolygonMesh& m) {
  Faces out;
  for (std::size_t f = 0; f < m.face_count(); ++f) {
    const auto face = m.face(f);
    out.emplace_back(face.begin(), face.end());
  }
  return out;
}

void expect_position(const PolygonMesh& m, std::size_t v, double x, double y, double z) {
  ASSERT_LT(v, m.positions.size());
  EXPECT_EQ(m.positions[v].x, x) << "vertex " << v;
  EXPECT_EQ(m.positions[v].y, y) << "vertex " << v;
  EXPECT_EQ(m.positions[v].z, z) << "vertex " << v;
}

/// Reads `data` expecting an InputError whose message holds every one of `parts`.
void expect_error(std::string_view data, MeshFormat format, const std::string& name,
                  std::initializer_list<std::string_view> parts) {
  try {
    const MeshFile m = read_text(data, format, name);
    ADD_FAILURE() << "no error; read " << m.polygons.positions.size() << " vertices and "
                  << m.polygons.face_count() << " faces";
  } catch (const InputError& e) {
    const std::string message = e.what();
    for (const auto part : parts) {
      EXPECT_NE(message.find(part), std::string::npos)
          << "message \"" << message << "\" lacks \"" << part << "\"";
    }
  }
}

/// Binary file images, little- or big-endian.
class Bytes {
 public:
  explicit Bytes(bool big_endian = false) : big_(big_endian) {}
  Bytes& text(std::string_view s) {
    data_.append(s);
    return *this;
  }
  template <class T>
  Bytes& put(T v) {
    char b[sizeof(T)];
    std::memcpy(b, &v, sizeof(T));
    if (big_ == (std::endian::native == std::endian::little)) std::reverse(b, b + sizeof(T));
    data_.append(b, sizeof(T));
    return *this;
  }
  const std::string& str() const { return data_; }
  std::size_t size() const { return data_.size(); }

 private:
  bool big_;
  std::string data_;
};

// ---- OBJ ----

TEST(ReadObj, PolygonsOfAnySizeAndVertexSlashForms) {
  const auto m = read_text(
      "# a comment\n"
      "mtllib scene.mtl\n"
      "o thing\n"
      "v 0 0 0\n"
      "v 1 0 0   # trailing comment\n"
      "v 1 1 0\n"
      "v 0 1 0\n"
      "v 0.5 2 0 1.0\n"  // w coordinate: not a position
      "vt 0 0\nvn 0 0 1\n"
      "g group\ns 1\nusemtl red\n"
      "f 1 2 3\n"
      "f 1/1 2/1 3/1 4/1\n"
      "f 1//1 2//1 3//1 5//1 4//1\n"
      "f 4/1/1 3/1/1 5/1/1\n"
      "l 1 2\n",
      MeshFormat::Obj);
  EXPECT_EQ(m.format, MeshFormat::Obj);
  EXPECT_TRUE(m.has_vertex_list);
  ASSERT_EQ(m.polygons.positions.size(), 5u);
  expect_position(m.polygons, 4, 0.5, 2, 0);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}, {0, 1, 2, 3}, {0, 1, 2, 4, 3}, {3, 2, 4}}));
}

TEST(ReadObj, NegativeIndicesCountBackFromTheLastVertexSoFar) {
  const auto m = read_text(
      "v 0 0 0\nv 1 0 0\nv 0 1 0\n"
      "f -3 -2 -1\n"
      "v 5 5 5\n"
      "f -1 -2 1\n",
      MeshFormat::Obj);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}, {3, 2, 0}}));
}

TEST(ReadObj, DegenerateFacesAreKeptAsRead) {
  const auto m = read_text("v 0 0 0\nv 1 0 0\nf 1\nf 1 2\n", MeshFormat::Obj);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0}, {0, 1}}));
}

TEST(ReadObj, BackslashContinuesALineAndCrLfEndsOne) {
  const auto m =
      read_text("v 0 0 0\r\nv 1 0 \\\r\n 0\r\nv 0 1 0\r\nf 1 2 \\\n 3\r\n", MeshFormat::Obj);
  ASSERT_EQ(m.polygons.positions.size(), 3u);
  expect_position(m.polygons, 1, 1, 0, 0);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}}));
}

TEST(ReadObj, ForwardReferencesToLaterVerticesAreResolved) {
  const auto m = read_text("f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n", MeshFormat::Obj);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}}));
}

TEST(ReadObj, CoordinatesAreParsedToTheNearestDouble) {
  const auto m = read_text(
      "v 0.1 -1e-300 +123456789.123456789\nv 4.9406564584124654e-324 1e-400 -0\n", MeshFormat::Obj);
  expect_position(m.polygons, 0, 0.1, -1e-300, 123456789.123456789);
  expect_position(m.polygons, 1, std::numeric_limits<double>::denorm_min(), 0.0, 0.0);
  EXPECT_TRUE(std::signbit(m.polygons.positions[1].z));
}

TEST(ReadObj, BadInputNamesFileLineAndElement) {
  const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
  expect_error(tri + "f 1 2 9\n", MeshFormat::Obj, "a.obj",
               {"a.obj: line 4: face 0: vertex index 9 out of range (3 vertices)"});
  expect_error(tri + "f 1 2 3\nf 1 2 -4\n", MeshFormat::Obj, "a.obj",
               {"a.obj: line 5: face 1: vertex index -4 out of range (3 vertices)"});
  expect_error(tri + "f 1 2 0\n", MeshFormat::Obj, "a.obj", {"line 4", "face 0", "index 0"});
  expect_error(tri + "f 1 2 x\n", MeshFormat::Obj, "a.obj", {"line 4", "face 0", "'x'"});
  expect_error(tri + "f\n", MeshFormat::Obj, "a.obj", {"line 4", "face 0: no vertex index"});
  expect_error("v 0 0 0\nv nan 0 0\n", MeshFormat::Obj, "a.obj",
               {"a.obj: line 2: vertex 1: coordinate 'nan' is not finite"});
  expect_error("v 0 0 inf\n", MeshFormat::Obj, "a.obj", {"line 1", "vertex 0", "not finite"});
  expect_error("v 0 0 1e999\n", MeshFormat::Obj, "a.obj", {"line 1", "vertex 0", "not finite"});
  expect_error("v 0 0\n", MeshFormat::Obj, "a.obj", {"line 1", "vertex 0: expected 3"});
  expect_error("v 0 0 1.5.2\n", MeshFormat::Obj, "a.obj", {"line 1", "bad coordinate"});
  // A forward index past the end is reported at the face that used it.
  expect_error("f 1 2 3\nf 1 2 7\n" + tri, MeshFormat::Obj, "a.obj",
               {"a.obj: line 2: face 1: vertex index 7 out of range (3 vertices)"});
  expect_error("", MeshFormat::Obj, "a.obj", {"a.obj", "empty"});
  expect_error("\x7f\x45\x4c\x46\x02\x01\x01", MeshFormat::Obj, "a.obj",
               {"a.obj: line 1", "not an OBJ statement"});
  expect_error("hello world\n", MeshFormat::Obj, "a.obj", {"a.obj", "no vertex"});
}

// ---- PLY ----

// A PLY file image from a schema and values, in any encoding (test-side encoder).
struct PlyProp {
  std::string type;
  std::string name;
  std::string count_type;  // non-empty: a list
};
struct PlyElem {
  std::string name;
  std::vector<PlyProp> props;
  std::vector<std::vector<std::vector<double>>> records;  // record -> property -> values
};

void put_value(Bytes& b, const std::string& type, double v) {
  if (type == "char" || type == "int8")
    b.put(static_cast<std::int8_t>(v));
  else if (type == "uchar" || type == "uint8")
    b.put(static_cast<std::uint8_t>(v));
  else if (type == "short" || type == "int16")
    b.put(static_cast<std::int16_t>(v));
  else if (type == "ushort" || type == "uint16")
    b.put(static_cast<std::uint16_t>(v));
  else if (type == "int" || type == "int32")
    b.put(static_cast<std::int32_t>(v));
  else if (type == "uint" || type == "uint32")
    b.put(static_cast<std::uint32_t>(v));
  else if (type == "float" || type == "float32")
    b.put(static_cast<float>(v));
  else if (type == "double" || type == "float64")
    b.put(v);
  else
    ADD_FAILURE() << "test encoder: unknown type " << type;
}

std::string make_ply(const std::vector<PlyElem>& elements, PlyEncoding encoding) {
  const char* format = encoding == PlyEncoding::Ascii                ? "ascii"
                       : encoding == PlyEncoding::BinaryLittleEndian ? "binary_little_endian"
                                                                     : "binary_big_endian";
  Bytes b(encoding == PlyEncoding::BinaryBigEndian);
  b.text(std::string("ply\nformat ") + format + " 1.0\ncomment test\n");
  for (const auto& e : elements) {
    b.text("element " + e.name + " " + std::to_string(e.records.size()) + "\n");
    for (const auto& p : e.props) {
      b.text(p.count_type.empty()
                 ? "property " + p.type + " " + p.name + "\n"
                 : "property list " + p.count_type + " " + p.type + " " + p.name + "\n");
    }
  }
  b.text("end_header\n");
  for (const auto& e : elements) {
    for (const auto& record : e.records) {
      for (std::size_t k = 0; k < e.props.size(); ++k) {
        const auto& p = e.props[k];
        const auto& values = record[k];
        if (encoding == PlyEncoding::Ascii) {
          char buf[64];
          if (!p.count_type.empty()) b.text(std::to_string(values.size()) + " ");
          for (double v : values) {
            std::snprintf(buf, sizeof buf, "%.17g ", v);
            b.text(buf);
          }
        } else {
          if (!p.count_type.empty()) put_value(b, p.count_type, static_cast<double>(values.size()));
          for (double v : values)
            put_value(b, p.type, v);
        }
      }
      if (encoding == PlyEncoding::Ascii) b.text("\n");
    }
  }
  return b.str();
}

constexpr PlyEncoding kEncodings[] = {PlyEncoding::Ascii, PlyEncoding::BinaryLittleEndian,
                                      PlyEncoding::BinaryBigEndian};

std::string encoding_name(PlyEncoding e) {
  return e == PlyEncoding::Ascii ? "ascii" : e == PlyEncoding::BinaryLittleEndian ? "le" : "be";
}

// Extra properties before and after x y z, lists among them, and elements to skip before,
// between and after the ones read.
std::vector<PlyElem> busy_ply() {
  PlyElem material{"material", {{"uchar", "red", ""}, {"float", "shine", ""}}, {{{1}, {0.5}}}};
  PlyElem vertex{"vertex",
                 {{"uchar", "flags", ""},
                  {"float", "confidence", ""},
                  {"double", "x", ""},
                  {"float", "tags", "uchar"},
                  {"double", "y", ""},
                  {"double", "z", ""},
                  {"short", "label", ""}},
                 {}};
  const double coords[4][3] = {{0.1, -2.5, 3}, {1e-7, 4, -0.0}, {7, 8.25, 9}, {-1, -2, 1e10}};
  for (const auto& c : coords) {
    vertex.records.push_back({{3}, {0.25}, {c[0]}, {1, 2, 3}, {c[1]}, {c[2]}, {-7}});
  }
  PlyElem edge{"edge", {{"int", "vertex1", ""}, {"int", "vertex2", ""}}, {{{0}, {1}}, {{1}, {2}}}};
  PlyElem face{"face",
               {{"uchar", "material", ""},
                {"float", "texcoord", "uchar"},
                {"int", "vertex_indices", "uchar"},
                {"uchar", "red", ""}},
               {{{0}, {0.5, 0.5}, {0, 1, 2}, {255}},
                {{0}, {}, {0, 2, 3, 1}, {0}},
                {{1}, {1, 2, 3}, {3, 2}, {9}}}};
  PlyElem tail{"comment_block", {{"uchar", "bytes", "uint"}}, {{{1, 2, 3, 4, 5}}, {{}}}};
  return {material, vertex, edge, face, tail};
}

TEST(ReadPly, SkipsOtherPropertiesAndElementsInEveryEncoding) {
  for (const auto encoding : kEncodings) {
    SCOPED_TRACE(encoding_name(encoding));
    const auto m = read_text(make_ply(busy_ply(), encoding), MeshFormat::Ply);
    EXPECT_EQ(m.format, MeshFormat::Ply);
    ASSERT_EQ(m.polygons.positions.size(), 4u);
    expect_position(m.polygons, 0, 0.1, -2.5, 3);
    expect_position(m.polygons, 1, 1e-7, 4, -0.0);
    expect_position(m.polygons, 3, -1, -2, 1e10);
    EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}, {0, 2, 3, 1}, {3, 2}}));
  }
}

TEST(ReadPly, CoordinatesOfEveryScalarTypeAndListTypes) {
  const char* types[] = {"char",   "int8",    "uchar",  "uint8",  "short", "int16",
                         "ushort", "uint16",  "int",    "int32",  "uint",  "uint32",
                         "float",  "float32", "double", "float64"};
  const char* counts[] = {"uchar", "uint8", "ushort", "uint16", "uint", "uint32", "char", "int"};
  const char* indices[] = {"int", "uint", "short", "ushort", "uchar", "char", "int32", "uint32"};
  for (const auto encoding : kEncodings) {
    for (std::size_t t = 0; t < std::size(types); ++t) {
      SCOPED_TRACE(encoding_name(encoding) + " " + types[t] + " " + counts[t % 8] + " " +
                   indices[t % 8]);
      PlyElem vertex{"vertex", {{types[t], "x", ""}, {types[t], "y", ""}, {types[t], "z", ""}}, {}};
      for (int v = 0; v < 4; ++v)
        vertex.records.push_back({{v + 1.0}, {100.0}, {v * 10.0}});
      PlyElem face{"face", {{indices[t % 8], "vertex_index", counts[t % 8]}}, {{{3, 2, 1, 0}}}};
      const auto m = read_text(make_ply({vertex, face}, encoding), MeshFormat::Ply);
      ASSERT_EQ(m.polygons.positions.size(), 4u);
      expect_position(m.polygons, 3, 4, 100, 30);
      EXPECT_EQ(faces_of(m.polygons), (Faces{{3, 2, 1, 0}}));
    }
  }
}

TEST(ReadPly, BinaryBigAndLittleEndianGiveTheSameBits) {
  PlyElem vertex{"vertex",
                 {{"double", "x", ""}, {"float", "y", ""}, {"int", "z", ""}},
                 {{{0.1}, {0.1f}, {-70000}}}};
  const auto le = read_text(make_ply({vertex}, PlyEncoding::BinaryLittleEndian), MeshFormat::Ply);
  const auto be = read_text(make_ply({vertex}, PlyEncoding::BinaryBigEndian), MeshFormat::Ply);
  expect_position(le.polygons, 0, 0.1, static_cast<double>(0.1f), -70000);
  expect_position(be.polygons, 0, 0.1, static_cast<double>(0.1f), -70000);
}

std::vector<PlyElem> tetra_ply() {
  return {PlyElem{"vertex",
                  {{"float", "x", ""}, {"float", "y", ""}, {"float", "z", ""}},
                  {{{0}, {0}, {0}}, {{1}, {0}, {0}}, {{0}, {1}, {0}}, {{0}, {0}, {1}}}},
          PlyElem{"face",
                  {{"int", "vertex_indices", "uchar"}},
                  {{{0, 2, 1}}, {{0, 1, 3}}, {{1, 2, 3}}, {{2, 0, 3}}}}};
}

TEST(ReadPly, IndexOutOfRangeNamesTheByteOrLine) {
  auto elements = tetra_ply();
  elements[1].records[1][0] = {0, 1, 7};
  // Binary: header, 4 vertices of 12 bytes, face 0 (13 bytes), face 1's count and two indices.
  for (const auto encoding : {PlyEncoding::BinaryLittleEndian, PlyEncoding::BinaryBigEndian}) {
    const std::string ply = make_ply(elements, encoding);
    const std::size_t header = ply.find("end_header\n") + 11;
    expect_error(ply, MeshFormat::Ply, "t.ply",
                 {"t.ply: byte " + std::to_string(header + 48 + 13 + 1 + 8) +
                  ": face 1: vertex index 7 out of range (4 vertices)"});
  }
  // Ascii: 10 header lines, 4 vertex lines, face 1 on line 16.
  expect_error(make_ply(elements, PlyEncoding::Ascii), MeshFormat::Ply, "t.ply",
               {"t.ply: line 16: face 1: vertex index 7 out of range (4 vertices)"});
  elements[1].records[1][0] = {0, 1, -1};
  expect_error(make_ply(elements, PlyEncoding::BinaryLittleEndian), MeshFormat::Ply, "t.ply",
               {"face 1: vertex index -1 out of range (4 vertices)"});
}

TEST(ReadPly, TruncatedBinaryIsRefused) {
  const std::string full = make_ply(tetra_ply(), PlyEncoding::BinaryLittleEndian);
  ASSERT_NO_THROW(read_text(full, MeshFormat::Ply));
  const std::size_t header = full.find("end_header\n") + 11;
  // Inside the last face's indices: found while reading them.
  expect_error(full.substr(0, full.size() - 2), MeshFormat::Ply, "t.ply",
               {"t.ply: byte " + std::to_string(full.size() - 13 + 1), "face 3", "truncated"});
  // Inside the vertices: the counts cannot fit, refused before anything is read.
  expect_error(full.substr(0, header + 30), MeshFormat::Ply, "t.ply",
               {"t.ply: byte " + std::to_string(header), "element vertex 4"});
  expect_error(full + "xx", MeshFormat::Ply, "t.ply",
               {"byte " + std::to_string(full.size()), "2 bytes after the last element"});
  const std::string ascii = make_ply(tetra_ply(), PlyEncoding::Ascii);
  expect_error(ascii.substr(0, ascii.size() - 4), MeshFormat::Ply, "t.ply",
               {"t.ply: line 18", "face 3", "truncated"});
}

TEST(ReadPly, AHugeCountInASmallFileIsAnErrorNotAnAllocation) {
  const std::string header =
      "ply\nformat binary_little_endian 1.0\nelement vertex 4000000000\n"
      "property float x\nproperty float y\nproperty float z\nend_header\n";
  expect_error(header + std::string(100, '\0'), MeshFormat::Ply, "big.ply",
               {"big.ply: byte " + std::to_string(header.size()), "element vertex 4000000000",
                "100 bytes follow"});
  const std::string list =
      "ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n"
      "property float y\nproperty float z\nelement face 1\n"
      "property list uint int vertex_indices\nend_header\n";
  Bytes b;
  b.text(list).put(0.f).put(0.f).put(0.f).put(std::uint32_t{4000000000u}).put(std::int32_t{0});
  expect_error(b.str(), MeshFormat::Ply, "big.ply",
               {"big.ply: byte " + std::to_string(list.size() + 16), "face 0", "truncated"});
}

TEST(ReadPly, NonFiniteCoordinatesAreRefused) {
  PlyElem vertex{"vertex",
                 {{"float", "x", ""}, {"double", "y", ""}, {"float", "z", ""}},
                 {{{0}, {0}, {0}}, {{1}, {std::nan("")}, {0}}}};
  const std::string le = make_ply({vertex}, PlyEncoding::BinaryLittleEndian);
  const std::size_t header = le.find("end_header\n") + 11;
  expect_error(
      le, MeshFormat::Ply, "n.ply",
      {"n.ply: byte " + std::to_string(header + 16 + 4), "vertex 1: coordinate y is not finite"});
  vertex.records[1][2] = {std::numeric_limits<double>::infinity()};
  vertex.records[1][1] = {0};
  expect_error(make_ply({vertex}, PlyEncoding::Ascii), MeshFormat::Ply, "n.ply",
               {"n.ply: line 10: vertex 1: coordinate z is not finite"});
}

TEST(ReadPly, BadHeadersAreRefusedWithTheirLine) {
  expect_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n0\n",
               MeshFormat::Ply, "h.ply", {"h.ply: line 4: unknown property type 'float128'"});
  expect_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nend_header\n0\n",
               MeshFormat::Ply, "h.ply", {"h.ply: line 3", "no y property"});
  expect_error("ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\n", MeshFormat::Ply,
               "h.ply", {"h.ply", "no end_header"});
  expect_error("ply\nformat binary_middle_endian 1.0\n", MeshFormat::Ply, "h.ply",
               {"h.ply: line 2", "unknown PLY format"});
  expect_error(
      "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
      "property float z\nelement face 0\nproperty list float int vertex_indices\nend_header\n",
      MeshFormat::Ply, "h.ply", {"h.ply: line 8", "count type must be an integer"});
  expect_error("", MeshFormat::Ply, "h.ply", {"h.ply", "empty"});
  expect_error("solid x\nfacet normal 0 0 0\n", MeshFormat::Ply, "h.ply",
               {"h.ply: line 1", "not a PLY file"});
  expect_error(
      "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n"
      "property float z\nend_header\n1 2 zz\n",
      MeshFormat::Ply, "h.ply", {"h.ply: line 8: vertex 0: bad number 'zz'"});
}

// Blender 2.4x's PLY exporter wrote its banner into the header without `comment` (assimp's
// test model cube_blender247.ply starts this way). Readers skip such lines; so does this one,
// naming the line in a warning, and every known keyword stays strict.
TEST(ReadPly, HeaderLinesOfUnknownKindAreSkippedWithAWarning) {
  const std::string blender =
      "ply\nformat ascii 1.0\nCreated by Blender3D 247 - www.blender.org, source file: ''\n"
      "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
      "element face 1\nproperty list uchar uint vertex_indices\nend_header\n"
      "0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  const auto m = read_text(blender, MeshFormat::Ply, "b.ply");
  ASSERT_EQ(m.polygons.positions.size(), 3u);
  expect_position(m.polygons, 1, 1, 0, 0);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}}));
  ASSERT_EQ(m.warnings.size(), 1u);
  EXPECT_NE(m.warnings[0].find("b.ply: line 3: "), std::string::npos) << m.warnings[0];
  EXPECT_NE(m.warnings[0].find("'Created by Blender3D 247"), std::string::npos) << m.warnings[0];

  // Known files give no warning; comments and obj_info are not unknown.
  const auto plain = read_text(make_ply(tetra_ply(), PlyEncoding::BinaryLittleEndian),
                               MeshFormat::Ply);
  EXPECT_TRUE(plain.warnings.empty());

  // Binary bodies too: the skipped line moves the body offset like any other header line.
  std::string binary = make_ply(tetra_ply(), PlyEncoding::BinaryBigEndian);
  binary.insert(binary.find("element"), "exported by some tool\n");
  const auto b = read_text(binary, MeshFormat::Ply, "be.ply");
  EXPECT_EQ(b.polygons.positions.size(), 4u);
  ASSERT_EQ(b.warnings.size(), 1u);
  EXPECT_NE(b.warnings[0].find("be.ply: line 4: "), std::string::npos) << b.warnings[0];

  // Everything else stays strict: a bad format, a property before any element, an unknown type.
  expect_error("ply\nformat ascii 2.0\nCreated by Blender3D\n", MeshFormat::Ply, "s.ply",
               {"s.ply: line 2", "unsupported PLY version"});
  expect_error("ply\nformat ascii 1.0\nCreated by Blender3D\nproperty float x\nend_header\n",
               MeshFormat::Ply, "s.ply", {"s.ply: line 4", "a property before any element"});
  expect_error("ply\nCreated by Blender3D\nelement vertex 0\nend_header\n", MeshFormat::Ply,
               "s.ply", {"s.ply", "no format line"});
}

TEST(ReadPly, EmptyFaceIsAnErrorButShortFacesAreKept) {
  auto elements = tetra_ply();
  elements[1].records = {{{0, 1}}, {{2}}};
  const auto m = read_text(make_ply(elements, PlyEncoding::Ascii), MeshFormat::Ply);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1}, {2}}));
  elements[1].records = {{{0, 1, 2}}, {{}}};
  expect_error(make_ply(elements, PlyEncoding::BinaryLittleEndian), MeshFormat::Ply, "e.ply",
               {"e.ply: byte", "face 1: no vertex index"});
}

// ---- STL ----

TEST(ReadStl, AsciiFacetsBecomeATriangleSoup) {
  const auto m = read_text(
      "solid part name\n"
      "  facet normal 0 0 1\n    outer loop\n      vertex 0 0 0\n      vertex 1 0 0\n"
      "      vertex 0 1 0\n    endloop\n  endfacet\n"
      "  FACET NORMAL 0 0 -1\n    OUTER LOOP\n      VERTEX 0 0 0\n      VERTEX 0 1 0\n"
      "      VERTEX 1 0.5 1e-3\n    ENDLOOP\n  ENDFACET\n"
      "endsolid part name\n",
      MeshFormat::Stl);
  EXPECT_EQ(m.format, MeshFormat::Stl);
  EXPECT_FALSE(m.has_vertex_list);
  ASSERT_EQ(m.polygons.positions.size(), 6u);
  expect_position(m.polygons, 5, 1, 0.5, 1e-3);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}, {3, 4, 5}}));
}

std::string binary_stl(std::string_view header80, const std::vector<std::array<float, 9>>& tris) {
  Bytes b;
  std::string header(header80);
  header.resize(80, ' ');
  b.text(header).put(static_cast<std::uint32_t>(tris.size()));
  for (const auto& t : tris) {
    b.put(0.f).put(0.f).put(1.f);
    for (const float c : t)
      b.put(c);
    b.put(std::uint16_t{0});
  }
  return b.str();
}

const std::vector<std::array<float, 9>> kTwoTriangles = {
    {0, 0, 0, 1, 0, 0, 0, 1, 0}, {0.1f, 0.2f, 0.3f, -1, -2, -3, 1e20f, 0, 5}};

TEST(ReadStl, BinaryIncludingAHeaderThatStartsWithSolid) {
  for (const char* header : {"binary from some exporter", "solid this is binary all the same"}) {
    SCOPED_TRACE(header);
    const auto m = read_text(binary_stl(header, kTwoTriangles), MeshFormat::Stl);
    EXPECT_FALSE(m.has_vertex_list);
    ASSERT_EQ(m.polygons.positions.size(), 6u);
    expect_position(m.polygons, 3, 0.1f, 0.2f, 0.3f);
    expect_position(m.polygons, 5, 1e20f, 0, 5);
    EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 1, 2}, {3, 4, 5}}));
  }
}

TEST(ReadStl, TruncatedOrCorruptFilesAreRefused) {
  const std::string full = binary_stl("model", kTwoTriangles);
  expect_error(full.substr(0, full.size() - 7), MeshFormat::Stl, "s.stl",
               {"s.stl: byte 80", "2 triangles need 184 bytes", "truncated"});
  const std::string solid = binary_stl("solid but binary", kTwoTriangles);
  expect_error(solid.substr(0, solid.size() - 7), MeshFormat::Stl, "s.stl",
               {"s.stl: byte 80", "truncated"});
  expect_error(full.substr(0, 50), MeshFormat::Stl, "s.stl", {"s.stl: byte 50", "header"});
  auto nan_tris = kTwoTriangles;
  nan_tris[1][4] = std::numeric_limits<float>::quiet_NaN();
  expect_error(binary_stl("model", nan_tris), MeshFormat::Stl, "s.stl",
               {"s.stl: byte " + std::to_string(84 + 50 + 12 + 12 + 4),
                "triangle 1: vertex 1: coordinate is not finite"});
  expect_error("solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n",
               MeshFormat::Stl, "s.stl", {"s.stl: line 5", "truncated"});
  expect_error("solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 nan 0\n",
               MeshFormat::Stl, "s.stl", {"s.stl: line 5: facet 0: vertex 1", "not finite"});
  expect_error("solid a\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvortex 1 0 0\n",
               MeshFormat::Stl, "s.stl", {"s.stl: line 5", "'vortex'"});
  expect_error("", MeshFormat::Stl, "s.stl", {"s.stl", "empty"});
}

// ---- OFF ----

TEST(ReadOff, CountsVerticesFacesCommentsAndColours) {
  const auto m = read_text(
      "OFF\n# a cube corner\n4 3 0\n"
      "0 0 0\n1 0 0\n0 1 0  # comment\n\n0 0 1\n"
      "3 0 2 1 255 0 0\n"
      "4 0 1 3 2\n"
      "2 1 3\n",
      MeshFormat::Off);
  EXPECT_EQ(m.format, MeshFormat::Off);
  ASSERT_EQ(m.polygons.positions.size(), 4u);
  expect_position(m.polygons, 3, 0, 0, 1);
  EXPECT_EQ(faces_of(m.polygons), (Faces{{0, 2, 1}, {0, 1, 3, 2}, {1, 3}}));
  const auto coff = read_text("COFF 3 1 3\n0 0 0 1 0 0 1\n1 0 0 1 0 0 1\n0 2 0 1 0 0 1\n3 0 1 2\n",
                              MeshFormat::Off);
  expect_position(coff.polygons, 2, 0, 2, 0);
  EXPECT_EQ(faces_of(coff.polygons), (Faces{{0, 1, 2}}));
}

TEST(ReadOff, BadInputNamesFileLineAndElement) {
  const std::string head = "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n";
  expect_error(head + "3 0 1 3\n", MeshFormat::Off, "o.off",
               {"o.off: line 6: face 0: vertex index 3 out of range (3 vertices)"});
  expect_error(head + "3 0 1\n", MeshFormat::Off, "o.off", {"o.off: line 6: face 0", "2 found"});
  expect_error(head + "0\n", MeshFormat::Off, "o.off", {"line 6: face 0: no vertex index"});
  expect_error("OFF\n3 1 0\n0 0 0\n1 nan 0\n0 1 0\n3 0 1 2\n", MeshFormat::Off, "o.off",
               {"o.off: line 4: vertex 1: coordinate 'nan' is not finite"});
  expect_error("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n", MeshFormat::Off, "o.off",
               {"o.off: line 5", "before face 0", "truncated"});
  expect_error("OFF\n4000000000 1 0\n0 0 0\n", MeshFormat::Off, "o.off",
               {"o.off: line 2", "declares 4000000000 vertices"});
  expect_error(head + "3 0 1 2\n3 0 1 2\n", MeshFormat::Off, "o.off",
               {"o.off: line 7", "after the last face"});
  expect_error("PLY\n3 1 0\n", MeshFormat::Off, "o.off", {"o.off: line 1", "not an OFF file"});
  expect_error("", MeshFormat::Off, "o.off", {"o.off", "empty"});
}

// ---- Writers and round trips ----

class TempDir {
 public:
  TempDir() {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    path_ = std::filesystem::temp_directory_path() /
            (std::string("bisturi_mesh_io_") + info->name() + "_" + std::to_string(::getpid()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() { std::filesystem::remove_all(path_); }
  std::filesystem::path operator/(const std::string& name) const { return path_ / name; }

 private:
  std::filesystem::path path_;
};

// Doubles of every kind (tiny, huge, negative zero, denormal, 17-digit) and faces from 1 to 300
// corners.
PolygonMesh awkward_mesh() {
  PolygonMesh m;
  std::mt19937_64 rng(42);
  for (int i = 0; i < 400; ++i) {
    Dlfl::Vec3 p;
    for (int k = 0; k < 3; ++k) {
      double d;
      do {
        d = std::bit_cast<double>(rng());
      } while (!std::isfinite(d));
      p[k] = d;
    }
    m.positions.push_back(p);
  }
  m.positions.emplace_back(-0.0, std::numeric_limits<double>::denorm_min(), 0.1);
  m.positions.emplace_back(std::numeric_limits<double>::max(), -1e-310, 1.0 / 3.0);
  const std::size_t n = m.positions.size();
  for (std::size_t size : {3u, 4u, 5u, 1u, 2u, 255u, 256u, 300u, 3u}) {
    std::vector<std::uint32_t> face;
    for (std::size_t k = 0; k < size; ++k)
      face.push_back(static_cast<std::uint32_t>(rng() % n));
    m.add_face(face);
  }
  return m;
}

void expect_same_mesh(const PolygonMesh& a, const PolygonMesh& b) {
  ASSERT_EQ(a.positions.size(), b.positions.size());
  for (std::size_t v = 0; v < a.positions.size(); ++v) {
    for (int k = 0; k < 3; ++k) {
      ASSERT_EQ(std::bit_cast<std::uint64_t>(a.positions[v][k]),
                std::bit_cast<std::uint64_t>(b.positions[v][k]))
          << "vertex " << v << " axis " << k;
    }
  }
  EXPECT_EQ(a.indices, b.indices);
  EXPECT_EQ(a.offsets, b.offsets);
}

TEST(WriteMesh, ObjRoundTripIsBitExact) {
  const TempDir dir;
  const PolygonMesh mesh = awkward_mesh();
  write_obj(dir / "m.obj", mesh);
  expect_same_mesh(read_mesh(dir / "m.obj").polygons, mesh);
}

TEST(WriteMesh, PlyRoundTripIsBitExactInEveryEncoding) {
  const TempDir dir;
  const PolygonMesh mesh = awkward_mesh();
  for (const auto encoding : kEncodings) {
    SCOPED_TRACE(encoding_name(encoding));
    const auto file = dir / ("m_" + encoding_name(encoding) + ".PLY");
    write_ply(file, mesh, encoding);
    const MeshFile back = read_mesh(file);
    expect_same_mesh(back.polygons, mesh);
    EXPECT_EQ(back.source_bytes, std::filesystem::file_size(file));
  }
}

TEST(WriteMesh, PlyCountTypeIsUcharUnlessAFaceNeedsMore) {
  const TempDir dir;
  const auto header_of = [&](const PolygonMesh& m) {
    write_ply(dir / "h.ply", m, PlyEncoding::BinaryBigEndian);
    std::ifstream in(dir / "h.ply", std::ios::binary);
    std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    return text.substr(0, text.find("end_header"));
  };
  PolygonMesh small;
  small.positions.assign(300, Dlfl::Vec3(1.0));
  small.add_face({0, 1, 2});
  EXPECT_NE(header_of(small).find("property list uchar int vertex_indices"), std::string::npos);
  PolygonMesh wide = small;
  std::vector<std::uint32_t> big(256);
  for (std::uint32_t i = 0; i < 256; ++i)
    big[i] = i;
  wide.add_face(big);
  EXPECT_NE(header_of(wide).find("property list uint int vertex_indices"), std::string::npos);
  expect_same_mesh(read_mesh(dir / "h.ply").polygons, wide);
}

TEST(WriteMesh, InvalidMeshesAreRefused) {
  const TempDir dir;
  PolygonMesh m;
  m.positions = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  m.add_face({0, 1, 3});
  EXPECT_THROW(write_obj(dir / "bad.obj", m), InputError);
  m.indices.back() = 2;
  m.positions[1].y = std::nan("");
  EXPECT_THROW(write_ply(dir / "bad.ply", m), InputError);
  m.positions[1].y = 0;
  m.add_face(std::span<const std::uint32_t>{});
  EXPECT_THROW(write_ply(dir / "bad.ply", m), InputError);
  m.offsets.pop_back();
  EXPECT_NO_THROW(write_ply(dir / "good.ply", m));
}

// ---- Files, dispatch, progress ----

TEST(ReadMesh, FormatFollowsTheExtensionInAnyCase) {
  EXPECT_EQ(format_from_path("a/b.OBJ"), MeshFormat::Obj);
  EXPECT_EQ(format_from_path("b.Ply"), MeshFormat::Ply);
  EXPECT_EQ(format_from_path("b.stl"), MeshFormat::Stl);
  EXPECT_EQ(format_from_path("b.off"), MeshFormat::Off);
  try {
    (void)format_from_path("dir/mesh.dae");
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("dir/mesh.dae"), std::string::npos) << e.what();
  }
}

TEST(ReadMesh, MissingFileNamesIt) {
  const TempDir dir;
  const auto file = dir / "absent.stl";
  try {
    (void)read_mesh(file);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
  }
}

TEST(ReadMesh, ErrorsFromFilesNameThePath) {
  const TempDir dir;
  const auto file = dir / "broken.off";
  std::ofstream(file) << "OFF\n1 1 0\n0 0 0\n3 0 1 2\n";
  try {
    (void)read_mesh(file);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string() + ": line 4: face 0"), std::string::npos)
        << e.what();
  }
}

TEST(ReadMesh, ProgressIsReportedAboutEveryMegabyte) {
  std::string obj;
  for (int i = 0; i < 200000; ++i)
    obj += "v 0.123456789 1.23456789 12.3456789\n";
  for (int i = 1; i + 2 <= 200000; i += 3) {
    obj +=
        "f " + std::to_string(i) + " " + std::to_string(i + 1) + " " + std::to_string(i + 2) + "\n";
  }
  std::vector<std::pair<std::size_t, std::size_t>> calls;
  ReadOptions options;
  options.progress = [&](std::size_t done, std::size_t total) { calls.emplace_back(done, total); };
  const auto m = read_mesh_from_memory(bytes_of(obj), MeshFormat::Obj, "p.obj", options);
  EXPECT_EQ(m.polygons.positions.size(), 200000u);
  const std::size_t megabytes = obj.size() >> 20;
  ASSERT_GE(calls.size(), megabytes);
  EXPECT_LE(calls.size(), megabytes + 2);
  for (std::size_t i = 0; i < calls.size(); ++i) {
    EXPECT_EQ(calls[i].second, obj.size());
    if (i > 0) {
      EXPECT_GT(calls[i].first, calls[i - 1].first);
    }
  }
  EXPECT_EQ(calls.back().first, obj.size());
}

}  // namespace
}  // namespace bisturi
