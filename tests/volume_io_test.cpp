// Volume readers and writers: round trips, hand-built NRRD and NIfTI headers, DICOM series
// written here with GDCM, and the errors (each names the file and the problem). Every file is
// made by the test in a temporary folder.

#include <gdcmAttribute.h>
#include <gdcmDataSet.h>
#include <gdcmMediaStorage.h>
#include <gdcmUIDGenerator.h>
#include <gdcmWriter.h>
#include <gtest/gtest.h>
#include <unistd.h>
#include <zlib.h>

#include <bit>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "bisturi/scene/errors.h"
#include "bisturi/scene/volume/volume_io.h"

namespace bisturi {
namespace {

namespace fs = std::filesystem;

class VolumeIo : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("bisturi_volume_io_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path path(const std::string& name) const { return dir_ / name; }

  fs::path write(const std::string& name, const std::string& bytes) const {
    const fs::path p = path(name);
    fs::create_directories(p.parent_path());
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    return p;
  }

  fs::path dir_;
};

// Expects InputError whose message contains the file and every fragment.
template <class F>
void expect_error(F&& f, const std::vector<std::string>& fragments) {
  try {
    f();
    ADD_FAILURE() << "no InputError";
  } catch (const InputError& e) {
    const std::string m = e.what();
    for (const auto& s : fragments) {
      EXPECT_NE(m.find(s), std::string::npos) << "'" << s << "' not in: " << m;
    }
  }
}

std::string bytes_of(const void* p, std::size_t n) {
  return {static_cast<const char*>(p), n};
}

std::string gzip(const std::string& data) {
  z_stream z{};
  EXPECT_EQ(deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
  std::string out(deflateBound(&z, static_cast<uLong>(data.size())) + 64, '\0');
  z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
  z.avail_in = static_cast<uInt>(data.size());
  z.next_out = reinterpret_cast<Bytef*>(out.data());
  z.avail_out = static_cast<uInt>(out.size());
  EXPECT_EQ(deflate(&z, Z_FINISH), Z_STREAM_END);
  out.resize(z.total_out);
  deflateEnd(&z);
  return out;
}

glm::dmat3 rotation(double angle, glm::dvec3 axis) {
  axis = glm::normalize(axis);
  const double c = std::cos(angle), s = std::sin(angle);
  glm::dmat3 k(0.0);
  k[1][0] = axis.z;
  k[2][0] = -axis.y;
  k[0][1] = -axis.z;
  k[2][1] = axis.x;
  k[0][2] = axis.y;
  k[1][2] = -axis.x;
  return glm::dmat3(1.0) + s * k + (1.0 - c) * k * k;
}

Volume oblique_volume() {
  Volume v;
  v.geometry.dims = {5, 4, 3};
  v.geometry.spacing = {0.5, 0.75, 2.5};
  v.geometry.origin = {-12.25, 30.5, 101.0};
  v.geometry.direction = rotation(0.3, {1.0, 2.0, 0.5});
  v.geometry.direction[2] = -v.geometry.direction[2];  // a left-handed index frame too
  v.values.resize(v.geometry.voxel_count());
  for (std::size_t n = 0; n < v.values.size(); ++n) {
    v.values[n] = static_cast<float>(n) * 1.37f - 20.0f;
  }
  v.values[3] = -0.0f;
  v.values[7] = 1e-40f;  // denormal
  v.values[11] = std::numeric_limits<float>::quiet_NaN();
  v.values[12] = std::numeric_limits<float>::infinity();
  return v;
}

void expect_same_geometry(const VolumeGeometry& a, const VolumeGeometry& b, double tol) {
  EXPECT_EQ(a.dims, b.dims);
  for (int i = 0; i < 3; ++i) {
    EXPECT_NEAR(a.spacing[i], b.spacing[i], tol) << "spacing " << i;
    EXPECT_NEAR(a.origin[i], b.origin[i], tol * 100) << "origin " << i;
    for (int j = 0; j < 3; ++j) {
      EXPECT_NEAR(a.direction[i][j], b.direction[i][j], tol) << "direction " << i << j;
    }
  }
}

void expect_same_bits(const Volume& a, const Volume& b) {
  ASSERT_EQ(a.values.size(), b.values.size());
  EXPECT_EQ(std::memcmp(a.values.data(), b.values.data(), a.values.size() * sizeof(float)), 0);
}

TEST_F(VolumeIo, NrrdRoundTripRawAndGzip) {
  Volume v = oblique_volume();
  v.modality = "MR";
  for (const NrrdEncoding e : {NrrdEncoding::Raw, NrrdEncoding::Gzip}) {
    const fs::path p = path(e == NrrdEncoding::Raw ? "raw.nrrd" : "gzip.nrrd");
    write_nrrd(p, v, e);
    std::size_t last_done = 0, last_total = 1;
    VolumeReadOptions options;
    options.progress = [&](std::size_t done, std::size_t total) {
      last_done = done;
      last_total = total;
    };
    const VolumeFile f = read_volume_file(p, options);
    EXPECT_EQ(f.format, VolumeFormat::Nrrd);
    EXPECT_EQ(f.stored_type, "float32");
    EXPECT_EQ(f.volume.source, p.string());
    EXPECT_EQ(f.volume.modality, "MR");
    expect_same_geometry(f.volume.geometry, v.geometry, 1e-12);
    expect_same_bits(f.volume, v);
    EXPECT_EQ(last_done, last_total);
    EXPECT_EQ(last_total, v.values.size() * 4);
  }
}

TEST_F(VolumeIo, NiftiRoundTripPlainAndGzip) {
  const Volume v = oblique_volume();
  for (const char* name : {"v.nii", "v.nii.gz"}) {
    const fs::path p = path(name);
    write_nifti(p, v);
    const VolumeFile f = read_volume_file(p);
    EXPECT_EQ(f.format, VolumeFormat::Nifti);
    EXPECT_FALSE(f.rescaled);
    // NIfTI stores the geometry as float32.
    expect_same_geometry(f.volume.geometry, v.geometry, 2e-6);
    expect_same_bits(f.volume, v);
  }
}

TEST_F(VolumeIo, NiftiRoundTripThroughQform) {
  // The writer's qform alone (sform_code cleared) gives the same geometry.
  const Volume v = oblique_volume();
  write_nifti(path("v.nii"), v);
  std::ifstream in(path("v.nii"), std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  const std::int16_t zero = 0;
  std::memcpy(bytes.data() + 254, &zero, 2);
  const Volume r = read_nifti_from_memory(std::as_bytes(std::span(bytes)), "q.nii");
  expect_same_geometry(r.geometry, v.geometry, 2e-6);
}

TEST_F(VolumeIo, NrrdRasSpaceBecomesLps) {
  const std::string header =
      "NRRD0004\n# a comment\ntype: uchar\ndimension: 3\nspace: right-anterior-superior\n"
      "sizes: 2 2 1\nspace directions: (2,0,0) (0,3,0) (0,0,4)\nkinds: domain domain domain\n"
      "encoding: raw\nspace origin: (10,20,30)\nkey:=value\n\n";
  const fs::path p = write("ras.nrrd", header + std::string("\x01\x02\x03\xff", 4));
  const Volume v = read_volume(p);
  EXPECT_EQ(v.geometry.dims, (std::array<std::int64_t, 3>{2, 2, 1}));
  EXPECT_EQ(v.geometry.spacing, glm::dvec3(2, 3, 4));
  EXPECT_EQ(v.geometry.origin, glm::dvec3(-10, -20, 30));
  EXPECT_EQ(v.geometry.direction[0], glm::dvec3(-1, 0, 0));
  EXPECT_EQ(v.geometry.direction[1], glm::dvec3(0, -1, 0));
  EXPECT_EQ(v.geometry.direction[2], glm::dvec3(0, 0, 1));
  EXPECT_EQ(std::vector<float>(v.values.begin(), v.values.end()),
            (std::vector<float>{1, 2, 3, 255}));
  // The same world point either way.
  const glm::dvec3 w = v.geometry.index_to_world({1, 1, 0});
  EXPECT_EQ(w, glm::dvec3(-12, -23, 30));  // RAS (12, 23, 30)
}

TEST_F(VolumeIo, NrrdSpacingsOnlyAscii) {
  const fs::path p =
      write("a.nrrd",
            "NRRD0001\ntype: float\ndimension: 3\nsizes: 3 1 2\nspacings: 0.5 0.5 2\n"
            "encoding: ascii\n\n1 2.5 -3\n4e2\t5 6\n");
  const Volume v = read_volume(p);
  EXPECT_EQ(v.geometry.spacing, glm::dvec3(0.5, 0.5, 2));
  EXPECT_EQ(v.geometry.direction, glm::dmat3(1.0));
  EXPECT_EQ(v.geometry.origin, glm::dvec3(0.0));
  EXPECT_EQ(std::vector<float>(v.values.begin(), v.values.end()),
            (std::vector<float>{1, 2.5f, -3, 400, 5, 6}));
}

TEST_F(VolumeIo, NrrdInt16BigEndian) {
  const std::int16_t values[4] = {-1024, 3071, 0, -1};
  std::string data;
  for (const std::int16_t s : values) {
    const auto u = static_cast<std::uint16_t>(s);
    data += static_cast<char>(u >> 8);
    data += static_cast<char>(u & 0xff);
  }
  const fs::path p = write("be.nrrd",
                           "NRRD0004\ntype: signed short int\ndimension: 3\nspace: LPS\n"
                           "sizes: 4 1 1\nendian: big\nencoding: raw\n\n" +
                               data);
  const VolumeFile f = read_volume_file(p);
  EXPECT_EQ(f.stored_type, "int16");
  EXPECT_EQ(std::vector<float>(f.volume.values.begin(), f.volume.values.end()),
            (std::vector<float>{-1024, 3071, 0, -1}));
}

TEST_F(VolumeIo, NrrdGzipAndByteSkip) {
  std::string raw;
  for (std::uint16_t n = 0; n < 24; ++n)
    raw += bytes_of(&n, 2);
  const std::string header =
      "NRRD0005\ntype: ushort\ndimension: 3\nspace: left-anterior-superior\nsizes: 2 3 4\n"
      "space directions: (1,0,0) (0,1,0) (0,0,1)\nendian: little\nencoding: gzip\n";
  const Volume v = read_volume(write("g.nrrd", header + "\n" + gzip(raw)));
  EXPECT_EQ(v.geometry.direction[1], glm::dvec3(0, -1, 0));  // LAS: y flips
  for (std::size_t n = 0; n < 24; ++n)
    EXPECT_EQ(v.values[n], static_cast<float>(n));
  // byte skip counts decompressed bytes for gzip.
  const Volume s = read_volume(write("s.nrrd", header + "byte skip: 6\n\n" + gzip("junk!!" + raw)));
  EXPECT_EQ(s.values[23], 23.0f);
}

TEST_F(VolumeIo, NrrdDetachedHeaderAndFourDimensions) {
  std::string raw;
  for (float x = 0; x < 8; x += 1)
    raw += bytes_of(&x, 4);
  write("data/values.raw", "XXXX" + raw);
  const fs::path h = write("data/head.nhdr",
                           "NRRD0004\ntype: float\ndimension: 4\nspace: left-posterior-superior\n"
                           "sizes: 1 2 2 2\nspace directions: none (0,0.5,0) (0.5,0,0) (0,0,1)\n"
                           "kinds: scalar domain domain domain\nendian: little\nencoding: raw\n"
                           "byte skip: -1\ndata file: values.raw\n");
  const Volume v = read_volume(h);
  EXPECT_EQ(v.geometry.dims, (std::array<std::int64_t, 3>{2, 2, 2}));
  EXPECT_EQ(v.geometry.spacing, glm::dvec3(0.5, 0.5, 1));
  EXPECT_EQ(v.geometry.direction[0], glm::dvec3(0, 1, 0));
  EXPECT_EQ(v.values[7], 7.0f);
  // From memory, detached data needs a folder.
  expect_error(
      [&] {
        const std::string text =
            "NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"
            "endian: little\ndata file: values.raw\n";
        (void)read_nrrd_from_memory(std::as_bytes(std::span(text)), "mem.nhdr");
      },
      {"mem.nhdr: line 7: ", "detached"});
  // A missing data file is named.
  const fs::path bad = write("data/bad.nhdr",
                             "NRRD0004\ntype: float\ndimension: 3\nsizes: 1 1 1\nencoding: raw\n"
                             "endian: little\ndata file: nowhere.raw\n");
  expect_error([&] { (void)read_volume(bad); }, {"nowhere.raw", "cannot open"});
}

// A NIfTI-1 header (little endian unless `big`), filled by the caller through `set`.
struct NiftiHeader {
  std::string h = std::string(352, '\0');
  bool big = false;

  template <class T>
  void set(std::size_t offset, T value) {
    std::memcpy(h.data() + offset, &value, sizeof value);
    if (big)
      std::reverse(h.begin() + static_cast<std::ptrdiff_t>(offset),
                   h.begin() + static_cast<std::ptrdiff_t>(offset + sizeof value));
  }
  NiftiHeader(std::int16_t datatype, std::int16_t bitpix, std::array<std::int16_t, 3> dims,
              bool big_endian = false)
      : big(big_endian) {
    set<std::int32_t>(0, 348);
    set<std::int16_t>(40, 3);
    for (std::size_t a = 0; a < 3; ++a)
      set<std::int16_t>(42 + 2 * a, dims[a]);
    set<std::int16_t>(70, datatype);
    set<std::int16_t>(72, bitpix);
    set<float>(76, 1.0f);
    for (std::size_t a = 0; a < 3; ++a)
      set<float>(80 + 4 * a, 1.0f);
    set<float>(108, 352.0f);
    set<char>(123, 2);
    std::memcpy(h.data() + 344, "n+1", 4);
  }
};

TEST_F(VolumeIo, NiftiQformQuaternion) {
  NiftiHeader n(2, 8, {2, 1, 1});
  n.set<float>(80, 2.0f);
  n.set<float>(84, 3.0f);
  n.set<float>(88, 4.0f);
  n.set<std::int16_t>(252, 1);  // qform only
  const double s = std::sqrt(0.5);
  n.set<float>(264, static_cast<float>(s));  // 90 degrees about z: (a, b, c, d) = (s, 0, 0, s)
  n.set<float>(268, 10.0f);
  n.set<float>(272, 20.0f);
  n.set<float>(276, 30.0f);
  const std::string file = n.h + "\x05\x06";
  const Volume v = read_nifti_from_memory(std::as_bytes(std::span(file)), "q.nii");
  EXPECT_NEAR(glm::length(v.geometry.spacing - glm::dvec3(2, 3, 4)), 0.0, 1e-12);
  EXPECT_EQ(v.geometry.origin, glm::dvec3(-10, -20, 30));
  // RAS columns (0,1,0), (-1,0,0), (0,0,1) become LPS (0,-1,0), (1,0,0), (0,0,1).
  EXPECT_NEAR(glm::length(v.geometry.direction[0] - glm::dvec3(0, -1, 0)), 0.0, 1e-6);
  EXPECT_NEAR(glm::length(v.geometry.direction[1] - glm::dvec3(1, 0, 0)), 0.0, 1e-6);
  EXPECT_NEAR(glm::length(v.geometry.direction[2] - glm::dvec3(0, 0, 1)), 0.0, 1e-6);
  // qfac -1 flips +k.
  n.set<float>(76, -1.0f);
  const std::string flipped = n.h + "\x05\x06";
  const Volume f = read_nifti_from_memory(std::as_bytes(std::span(flipped)), "q.nii");
  EXPECT_NEAR(glm::length(f.geometry.direction[2] - glm::dvec3(0, 0, -1)), 0.0, 1e-6);
}

TEST_F(VolumeIo, NiftiRescaleBigEndianAndGzip) {
  NiftiHeader n(4, 16, {3, 1, 1}, /*big_endian=*/true);
  n.set<float>(112, 2.0f);
  n.set<float>(116, -1024.0f);
  n.set<char>(123, 1);  // metres
  n.set<float>(80, 0.001f);
  std::string data = n.h;
  for (const std::int16_t v : std::initializer_list<std::int16_t>{0, 512, 1000}) {
    const auto u = static_cast<std::uint16_t>(v);
    data += static_cast<char>(u >> 8);
    data += static_cast<char>(u & 0xff);
  }
  const fs::path p = write("r.nii.gz", gzip(data));
  const VolumeFile f = read_volume_file(p);
  EXPECT_TRUE(f.rescaled);
  EXPECT_EQ(f.stored_type, "int16");
  EXPECT_EQ(std::vector<float>(f.volume.values.begin(), f.volume.values.end()),
            (std::vector<float>{-1024, 0, 976}));
  EXPECT_NEAR(f.volume.geometry.spacing.x, 1.0, 1e-6);  // 0.001 m
  EXPECT_EQ(f.volume.geometry.direction[0], glm::dvec3(-1, 0, 0));
}

TEST_F(VolumeIo, NiftiErrors) {
  auto read = [](const std::string& bytes) {
    (void)read_nifti_from_memory(std::as_bytes(std::span(bytes)), "bad.nii");
  };
  NiftiHeader ok(16, 32, {2, 2, 2});
  const std::string values(32, '\0');
  EXPECT_NO_THROW(read(ok.h + values));
  expect_error([&] { read(ok.h + values.substr(0, 31)); }, {"bad.nii: byte 352: ", "truncated"});
  expect_error([&] { read(ok.h.substr(0, 200)); }, {"bad.nii: ", "truncated header"});
  expect_error([&] { read(gzip(ok.h + values.substr(0, 20))); }, {"bad.nii: ", "truncated"});
  NiftiHeader complex(32, 64, {2, 2, 2});
  expect_error([&] { read(complex.h + values + values); },
               {"bad.nii: byte 70: ", "unsupported datatype 32", "complex64"});
  NiftiHeader zero(16, 32, {2, 2, 2});
  zero.set<float>(84, 0.0f);
  expect_error([&] { read(zero.h + values); }, {"bad.nii: byte 84: ", "pixdim[2]", "spacing"});
  NiftiHeader nan(16, 32, {2, 2, 2});
  nan.set<float>(80, std::numeric_limits<float>::quiet_NaN());
  expect_error([&] { read(nan.h + values); }, {"bad.nii", "pixdim[1]"});
  NiftiHeader lying(16, 32, {2000, 2000, 2000});
  expect_error([&] { read(lying.h + values); }, {"bad.nii: byte 352: ", "truncated data"});
  NiftiHeader size0(16, 32, {2, 0, 2});
  expect_error([&] { read(size0.h); }, {"bad.nii: ", "size 0 along axis 1"});
  NiftiHeader off(16, 32, {2, 2, 2});
  off.set<float>(108, 100.0f);
  expect_error([&] { read(off.h + values); }, {"bad.nii: byte 108: ", "vox_offset"});
  NiftiHeader sform(16, 32, {2, 2, 2});
  sform.set<std::int16_t>(254, 1);  // sform of zeros
  expect_error([&] { read(sform.h + values); }, {"bad.nii: ", "zero spacing"});
  expect_error([&] { read(std::string(400, 'x')); }, {"bad.nii: byte 0: ", "not a NIfTI-1"});
}

TEST_F(VolumeIo, NrrdErrors) {
  const std::string good =
      "NRRD0004\ntype: short\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n";
  const std::string values(16, '\0');
  EXPECT_NO_THROW((void)read_volume(write("ok.nrrd", good + "\n" + values)));
  expect_error(
      [&] { (void)read_volume(write("trunc.nrrd", good + "\n" + values.substr(0, 15))); },
      {"trunc.nrrd: byte ", "truncated data: 15 bytes, the header needs 16", "2 x 2 x 2 int16"});
  const std::string lying =
      "NRRD0004\ntype: short\ndimension: 3\nsizes: 2000 2000 2000\nendian: little\n"
      "encoding: gzip\n\n";
  expect_error([&] { (void)read_volume(write("lying.nrrd", lying + gzip(values))); },
               {"lying.nrrd", "truncated data", "2000 x 2000 x 2000"});
  expect_error(
      [&] {
        (void)read_volume(write("huge.nrrd",
                                "NRRD0004\ntype: short\ndimension: 3\nsizes: "
                                "4000000000 4000000000 4000000000\nendian: little\n"
                                "encoding: raw\n\n"));
      },
      {"huge.nrrd: ", "overflow"});
  expect_error(
      [&] {
        (void)read_volume(write("type.nrrd",
                                "NRRD0004\ntype: quaternion\ndimension: 3\n"
                                "sizes: 1 1 1\nencoding: raw\n\n\x01"));
      },
      {"type.nrrd: line 2: ", "unknown or unsupported sample type 'quaternion'"});
  expect_error(
      [&] {
        (void)read_volume(write("zero.nrrd",
                                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\n"
                                "space: LPS\nspace directions: (1,0,0) (0,0,0) "
                                "(0,0,1)\nencoding: raw\n\n\x01"));
      },
      {"zero.nrrd: ", "zero spacing along index axis 1"});
  expect_error(
      [&] {
        (void)read_volume(write("sp.nrrd",
                                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\n"
                                "spacings: 1 nan 1\nencoding: raw\n\n\x01"));
      },
      {"sp.nrrd: line 5: ", "spacing 'nan' of axis 1"});
  expect_error(
      [&] {
        (void)read_volume(write("shear.nrrd",
                                "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 1 1\n"
                                "space: LPS\nspace directions: (1,0,0) (1,1,0) "
                                "(0,0,1)\nencoding: raw\n\n\x01"));
      },
      {"shear.nrrd: ", "not orthogonal"});
  expect_error(
      [&] {
        (void)read_volume(write("dim.nrrd",
                                "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 1 1\n"
                                "encoding: raw\n\n\x01"));
      },
      {"dim.nrrd: line 3: ", "only 3-D"});
  expect_error(
      [&] {
        (void)read_volume(write("noend.nrrd",
                                "NRRD0004\ntype: short\ndimension: 3\nsizes: 1 1 1\n"
                                "encoding: raw\n\n\x01\x02"));
      },
      {"noend.nrrd: ", "'endian'"});
  expect_error(
      [&] {
        (void)read_volume(write("asc.nrrd",
                                "NRRD0004\ntype: float\ndimension: 3\nsizes: 2 1 1\n"
                                "encoding: ascii\n\n1 x\n"));
      },
      {"asc.nrrd: byte ", "value 1: not a number: 'x'"});
  expect_error([&] { (void)read_volume(write("v.mha", "x")); },
               {"v.mha: ", "unknown volume format"});
  expect_error([&] { (void)read_volume(path("missing.nrrd")); }, {"missing.nrrd: ", "cannot open"});
}

void put_text(gdcm::DataSet& ds, std::uint16_t group, std::uint16_t element, gdcm::VR vr,
              std::string value) {
  if (value.size() % 2 != 0) value += vr == gdcm::VR::UI ? '\0' : ' ';
  gdcm::DataElement de(gdcm::Tag(group, element));
  de.SetVR(vr);
  de.SetByteValue(value.data(), static_cast<std::uint32_t>(value.size()));
  ds.Replace(de);
}

template <std::uint16_t G, std::uint16_t E>
void put_us(gdcm::DataSet& ds, std::uint16_t value) {
  gdcm::Attribute<G, E> a;
  a.SetValue(value);
  ds.Replace(a.GetAsDataElement());
}

// One CT slice written with GDCM: int16 stored values, RescaleIntercept -1024, 0.7 mm between
// columns and 0.8 mm between rows; rows run along +x, columns along -y.
void write_ct_slice(const fs::path& file, unsigned columns, unsigned rows, double z,
                    const std::string& series, std::int16_t base, double pixel_spacing_x = 0.7) {
  gdcm::Writer w;
  gdcm::DataSet& ds = w.GetFile().GetDataSet();
  const gdcm::MediaStorage ms(gdcm::MediaStorage::CTImageStorage);
  gdcm::UIDGenerator uids;
  put_text(ds, 0x0008, 0x0016, gdcm::VR::UI, ms.GetString());
  put_text(ds, 0x0008, 0x0018, gdcm::VR::UI, uids.Generate());
  put_text(ds, 0x0008, 0x0060, gdcm::VR::CS, "CT");
  put_text(ds, 0x0020, 0x000d, gdcm::VR::UI, "1.2.826.0.1.3680043.2.1125.7");
  put_text(ds, 0x0020, 0x000e, gdcm::VR::UI, series);
  std::ostringstream ipp;
  ipp << "-100\\-120\\" << z;
  put_text(ds, 0x0020, 0x0032, gdcm::VR::DS, ipp.str());
  put_text(ds, 0x0020, 0x0037, gdcm::VR::DS, "1\\0\\0\\0\\-1\\0");
  put_us<0x0028, 0x0002>(ds, 1);
  put_text(ds, 0x0028, 0x0004, gdcm::VR::CS, "MONOCHROME2");
  put_us<0x0028, 0x0010>(ds, static_cast<std::uint16_t>(rows));
  put_us<0x0028, 0x0011>(ds, static_cast<std::uint16_t>(columns));
  std::ostringstream ps;
  ps << "0.8\\" << pixel_spacing_x;  // row spacing, column spacing
  put_text(ds, 0x0028, 0x0030, gdcm::VR::DS, ps.str());
  put_us<0x0028, 0x0100>(ds, 16);
  put_us<0x0028, 0x0101>(ds, 16);
  put_us<0x0028, 0x0102>(ds, 15);
  put_us<0x0028, 0x0103>(ds, 1);
  put_text(ds, 0x0028, 0x1052, gdcm::VR::DS, "-1024");
  put_text(ds, 0x0028, 0x1053, gdcm::VR::DS, "1");
  std::vector<std::int16_t> pixels(static_cast<std::size_t>(columns) * rows);
  for (std::size_t n = 0; n < pixels.size(); ++n) {
    pixels[n] = static_cast<std::int16_t>(base + static_cast<std::int16_t>(n));
  }
  gdcm::DataElement pd(gdcm::Tag(0x7fe0, 0x0010));
  pd.SetVR(gdcm::VR::OW);
  pd.SetByteValue(reinterpret_cast<const char*>(pixels.data()),
                  static_cast<std::uint32_t>(pixels.size() * 2));
  ds.Replace(pd);
  w.GetFile().GetHeader().SetDataSetTransferSyntax(gdcm::TransferSyntax::ExplicitVRLittleEndian);
  w.SetFileName(file.string().c_str());
  ASSERT_TRUE(w.Write()) << file;
}

const std::string kSeries = "1.2.826.0.1.3680043.2.1125.1.42";

TEST_F(VolumeIo, DicomSeries) {
  const fs::path d = path("ct");
  fs::create_directories(d);
  // Written out of order; z positions 50, 52.5, ... (slice order comes from the positions).
  for (int k : {3, 0, 4, 2, 1}) {
    write_ct_slice(d / ("slice" + std::to_string(7 - k) + ".dcm"), 4, 3, 50.0 + 2.5 * k, kSeries,
                   static_cast<std::int16_t>(1000 + 100 * k));
  }
  write("ct/README.txt", "not a DICOM file");
  std::size_t calls = 0;
  VolumeReadOptions options;
  options.progress = [&](std::size_t, std::size_t) { ++calls; };
  const VolumeFile f = read_volume_file(d, options);
  const Volume& v = f.volume;
  EXPECT_EQ(f.format, VolumeFormat::DicomSeries);
  EXPECT_TRUE(f.rescaled);
  EXPECT_EQ(f.stored_type, "int16");
  EXPECT_EQ(v.modality, "CT");
  EXPECT_EQ(v.geometry.dims, (std::array<std::int64_t, 3>{4, 3, 5}));
  EXPECT_NEAR(v.geometry.spacing.x, 0.7, 1e-9);
  EXPECT_NEAR(v.geometry.spacing.y, 0.8, 1e-9);
  EXPECT_NEAR(v.geometry.spacing.z, 2.5, 1e-9);
  // Normal = row x col = (1,0,0) x (0,-1,0) = (0,0,-1): slices sorted along -z, first at z 60.
  EXPECT_NEAR(glm::length(v.geometry.origin - glm::dvec3(-100, -120, 60)), 0.0, 1e-9);
  EXPECT_NEAR(glm::length(v.geometry.direction[1] - glm::dvec3(0, -1, 0)), 0.0, 1e-12);
  EXPECT_NEAR(glm::length(v.geometry.direction[2] - glm::dvec3(0, 0, -1)), 0.0, 1e-12);
  // Slice k=4 (z 60) first: stored 1400 + n, minus 1024 HU.
  EXPECT_EQ(v.at(0, 0, 0), 1400.0f - 1024.0f);
  EXPECT_EQ(v.at(3, 2, 0), 1411.0f - 1024.0f);
  EXPECT_EQ(v.at(1, 0, 4), 1001.0f - 1024.0f);
  // Sample (i, j, k) sits where the slice file puts it.
  EXPECT_NEAR(glm::length(v.geometry.index_to_world({3, 2, 4}) - glm::dvec3(-97.9, -121.6, 50)),
              0.0, 1e-9);
  EXPECT_GT(calls, 5u);
}

TEST_F(VolumeIo, DicomErrors) {
  {  // A missing slice.
    const fs::path d = path("gap");
    fs::create_directories(d);
    for (int k : {0, 1, 3, 4}) {
      write_ct_slice(d / ("s" + std::to_string(k) + ".dcm"), 4, 3, 2.0 * k, kSeries, 0);
    }
    expect_error([&] { (void)read_volume(d); },
                 {d.string() + ": ", "missing slice", "s1.dcm", "s3.dcm", "gap of 4 mm"});
  }
  {  // Mixed slice sizes.
    const fs::path d = path("mixed");
    fs::create_directories(d);
    for (int k : {0, 1, 2}) {
      write_ct_slice(d / ("s" + std::to_string(k) + ".dcm"), k == 1 ? 5 : 4, 3, 2.0 * k, kSeries,
                     0);
    }
    expect_error([&] { (void)read_volume(d); },
                 {"s1.dcm: ", "slice size 5 x 3 differs from 4 x 3"});
  }
  {  // Mixed pixel spacing.
    const fs::path d = path("spacing");
    fs::create_directories(d);
    for (int k : {0, 1, 2}) {
      write_ct_slice(d / ("s" + std::to_string(k) + ".dcm"), 4, 3, 2.0 * k, kSeries, 0,
                     k == 2 ? 0.9 : 0.7);
    }
    expect_error([&] { (void)read_volume(d); }, {"s2.dcm: ", "pixel spacing"});
  }
  {  // Two series: listed, and one can be picked.
    const fs::path d = path("two");
    fs::create_directories(d);
    write_ct_slice(d / "a0.dcm", 4, 3, 0.0, kSeries, 0);
    write_ct_slice(d / "a1.dcm", 4, 3, 1.0, kSeries, 0);
    write_ct_slice(d / "b0.dcm", 4, 3, 0.0, "1.2.3.4", 0);
    expect_error([&] { (void)read_volume(d); }, {"2 series", kSeries, "1.2.3.4"});
    VolumeReadOptions pick;
    pick.series_uid = kSeries;
    EXPECT_EQ(read_volume(d, pick).geometry.dims[2], 2);
  }
  {  // No slices.
    const fs::path d = path("empty");
    fs::create_directories(d);
    write("empty/x.txt", "hello");
    expect_error([&] { (void)read_volume(d); }, {d.string() + ": ", "no DICOM image slices"});
  }
}

TEST_F(VolumeIo, ValueRangeAndWriterChecks) {
  Volume v = oblique_volume();
  const ValueRange r = value_range(v);
  EXPECT_EQ(r.finite_count, v.values.size() - 2);
  EXPECT_EQ(r.min, -20.0f);
  EXPECT_EQ(r.max, 59.0f * 1.37f - 20.0f);
  v.geometry.spacing.y = 0.0;
  expect_error([&] { write_nrrd(path("w.nrrd"), v); }, {"w.nrrd: ", "spacing 0"});
  v.geometry.spacing.y = 1.0;
  v.values.pop_back();
  expect_error([&] { write_nifti(path("w.nii"), v); }, {"w.nii: ", "59 values"});
  Volume empty;
  EXPECT_TRUE(std::isnan(value_range(empty).min));
}

}  // namespace
}  // namespace bisturi
