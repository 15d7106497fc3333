// write_nrrd and write_nifti: float32 samples with the geometry in each file's own frame.

#include <bit>
#include <cmath>
#include <cstring>
#include <string>

#include "../io/file_io.h"
#include "bisturi/scene/errors.h"
#include "volume_common.h"

namespace bisturi {

namespace {

static_assert(std::endian::native == std::endian::little, "the writers store little-endian data");

void check_writable(const std::filesystem::path& file, const Volume& v) {
  const std::string name = file.string();
  const VolumeGeometry& g = v.geometry;
  for (int a = 0; a < 3; ++a) {
    if (g.dims[static_cast<std::size_t>(a)] < 1) {
      throw InputError(mesh_io::cat(name, ": cannot write a volume of size ", g.dims[0], " x ",
                                    g.dims[1], " x ", g.dims[2]));
    }
    if (!(g.spacing[a] > 0.0) || !std::isfinite(g.spacing[a])) {
      throw InputError(mesh_io::cat(name, ": cannot write a volume with spacing ", g.spacing[a],
                                    " along axis ", a));
    }
    if (!std::isfinite(g.origin[a])) {
      throw InputError(mesh_io::cat(name, ": cannot write a volume whose origin is not finite"));
    }
    for (int b = 0; b < 3; ++b) {
      const double d = glm::dot(g.direction[a], g.direction[b]);
      if (!(std::abs(d - (a == b ? 1.0 : 0.0)) < 1e-6)) {
        throw InputError(
            mesh_io::cat(name, ": cannot write a volume whose direction is not orthonormal"));
      }
    }
  }
  if (v.values.size() != g.voxel_count()) {
    throw InputError(mesh_io::cat(name, ": cannot write a volume with ", v.values.size(),
                                  " values for ", g.dims[0], " x ", g.dims[1], " x ", g.dims[2],
                                  " samples"));
  }
}

std::string_view value_bytes(const Volume& v) {
  return {reinterpret_cast<const char*>(v.values.data()), v.values.size() * sizeof(float)};
}

std::string vec(const glm::dvec3& p) {
  return mesh_io::cat("(", p.x, ",", p.y, ",", p.z, ")");
}

template <class T>
void put(std::string& h, std::size_t offset, T value) {
  std::memcpy(h.data() + offset, &value, sizeof value);
}

}  // namespace

void write_nrrd(const std::filesystem::path& file, const Volume& volume, NrrdEncoding encoding) {
  check_writable(file, volume);
  const VolumeGeometry& g = volume.geometry;
  std::string h = "NRRD0004\n# bisturi volume (LPS millimetres)\ntype: float\ndimension: 3\n";
  h += "space: left-posterior-superior\n";
  h += mesh_io::cat("sizes: ", g.dims[0], " ", g.dims[1], " ", g.dims[2], "\n");
  h += "space directions:";
  for (int a = 0; a < 3; ++a) {
    h += ' ';
    h += vec(g.direction[a] * g.spacing[a]);
  }
  h += "\nkinds: domain domain domain\nendian: little\n";
  h += encoding == NrrdEncoding::Gzip ? "encoding: gzip\n" : "encoding: raw\n";
  h += "space origin: ";
  h += vec(g.origin);
  h += '\n';
  if (!volume.modality.empty() && volume.modality.find('\n') == std::string::npos) {
    h += "modality:=";
    h += volume.modality;
    h += '\n';
  }
  h += "\n";
  mesh_io::FileWriter out(file);
  out.write(h);
  if (encoding == NrrdEncoding::Gzip) {
    out.write(volume_io::gzip_compress(value_bytes(volume), file.string()));
  } else {
    out.write(value_bytes(volume));
  }
  out.close();
}

void write_nifti(const std::filesystem::path& file, const Volume& volume) {
  check_writable(file, volume);
  const VolumeGeometry& g = volume.geometry;
  std::string h(352, '\0');
  put<std::int32_t>(h, 0, 348);
  put<char>(h, 38, 'r');
  const std::int64_t kMaxDim = 32767;
  for (int a = 0; a < 3; ++a) {
    if (g.dims[static_cast<std::size_t>(a)] > kMaxDim) {
      throw InputError(mesh_io::cat(file.string(), ": NIfTI-1 sizes are at most 32767, not ",
                                    g.dims[static_cast<std::size_t>(a)]));
    }
  }
  const std::int16_t dims[8] = {3,
                                static_cast<std::int16_t>(g.dims[0]),
                                static_cast<std::int16_t>(g.dims[1]),
                                static_cast<std::int16_t>(g.dims[2]),
                                1,
                                1,
                                1,
                                1};
  std::memcpy(h.data() + 40, dims, sizeof dims);
  put<std::int16_t>(h, 70, 16);  // float32
  put<std::int16_t>(h, 72, 32);
  // The world in RAS: negate x and y.
  glm::dmat3 ras = g.direction;
  glm::dvec3 origin = g.origin;
  for (int a = 0; a < 3; ++a) {
    ras[a].x = -ras[a].x;
    ras[a].y = -ras[a].y;
  }
  origin.x = -origin.x;
  origin.y = -origin.y;
  double qfac = 1.0;
  glm::dmat3 r = ras;
  if (glm::determinant(r) < 0.0) {
    qfac = -1.0;
    r[2] = -r[2];
  }
  const float pixdim[8] = {static_cast<float>(qfac),
                           static_cast<float>(g.spacing[0]),
                           static_cast<float>(g.spacing[1]),
                           static_cast<float>(g.spacing[2]),
                           1.0f,
                           1.0f,
                           1.0f,
                           1.0f};
  std::memcpy(h.data() + 76, pixdim, sizeof pixdim);
  put<float>(h, 108, 352.0f);
  put<float>(h, 112, 0.0f);  // no rescale
  put<float>(h, 116, 0.0f);
  put<char>(h, 123, 2);  // millimetres
  put<std::int16_t>(h, 252, 1);
  put<std::int16_t>(h, 254, 1);
  // Quaternion of r (nifti_mat44_to_quatern); R(i, j) is row i, column j.
  auto R = [&r](int i, int j) { return r[j][i]; };
  double qa = R(0, 0) + R(1, 1) + R(2, 2) + 1.0, qb = 0, qc = 0, qd = 0;
  if (qa > 0.5) {
    qa = 0.5 * std::sqrt(qa);
    qb = 0.25 * (R(2, 1) - R(1, 2)) / qa;
    qc = 0.25 * (R(0, 2) - R(2, 0)) / qa;
    qd = 0.25 * (R(1, 0) - R(0, 1)) / qa;
  } else {
    const double xd = 1.0 + R(0, 0) - (R(1, 1) + R(2, 2));
    const double yd = 1.0 + R(1, 1) - (R(0, 0) + R(2, 2));
    const double zd = 1.0 + R(2, 2) - (R(0, 0) + R(1, 1));
    if (xd > 1.0) {
      qb = 0.5 * std::sqrt(xd);
      qc = 0.25 * (R(0, 1) + R(1, 0)) / qb;
      qd = 0.25 * (R(0, 2) + R(2, 0)) / qb;
      qa = 0.25 * (R(2, 1) - R(1, 2)) / qb;
    } else if (yd > 1.0) {
      qc = 0.5 * std::sqrt(yd);
      qb = 0.25 * (R(0, 1) + R(1, 0)) / qc;
      qd = 0.25 * (R(1, 2) + R(2, 1)) / qc;
      qa = 0.25 * (R(0, 2) - R(2, 0)) / qc;
    } else {
      qd = 0.5 * std::sqrt(zd);
      qb = 0.25 * (R(0, 2) + R(2, 0)) / qd;
      qc = 0.25 * (R(1, 2) + R(2, 1)) / qd;
      qa = 0.25 * (R(1, 0) - R(0, 1)) / qd;
    }
    if (qa < 0.0) {
      qb = -qb;
      qc = -qc;
      qd = -qd;
    }
  }
  put<float>(h, 256, static_cast<float>(qb));
  put<float>(h, 260, static_cast<float>(qc));
  put<float>(h, 264, static_cast<float>(qd));
  for (int i = 0; i < 3; ++i) {
    put<float>(h, 268 + 4 * static_cast<std::size_t>(i), static_cast<float>(origin[i]));
    const std::size_t row = 280 + 16 * static_cast<std::size_t>(i);
    for (int j = 0; j < 3; ++j) {
      put<float>(h, row + 4 * static_cast<std::size_t>(j),
                 static_cast<float>(ras[j][i] * g.spacing[j]));
    }
    put<float>(h, row + 12, static_cast<float>(origin[i]));
  }
  std::memcpy(h.data() + 148, "bisturi", 7);
  std::memcpy(h.data() + 344, "n+1", 4);

  mesh_io::FileWriter out(file);
  if (volume_io::ends_with_icase(file.string(), ".gz")) {
    std::string all = h;
    all += value_bytes(volume);
    out.write(volume_io::gzip_compress(all, file.string()));
  } else {
    out.write(h);
    out.write(value_bytes(volume));
  }
  out.close();
}

}  // namespace bisturi
