// DICOM series with GDCM: every file of a folder is read up to its pixel data, image slices are
// grouped by SeriesInstanceUID, sorted along the slice normal and checked (equal size, pixel
// spacing and orientation, uniform slice spacing); then each slice's pixels are read and
// rescaled (RescaleSlope / RescaleIntercept) into the volume. DICOM patient coordinates are LPS.

#include <gdcmAttribute.h>
#include <gdcmDataSet.h>
#include <gdcmImage.h>
#include <gdcmImageReader.h>
#include <gdcmPixelFormat.h>
#include <gdcmReader.h>
#include <gdcmTag.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <optional>
#include <system_error>
#include <vector>

#include "bisturi/scene/errors.h"
#include "readers.h"
#include "volume_common.h"

namespace bisturi::volume_io {

namespace {

std::optional<std::string> text_of(const gdcm::DataSet& ds, const gdcm::Tag& tag) {
  if (!ds.FindDataElement(tag)) return std::nullopt;
  const gdcm::DataElement& de = ds.GetDataElement(tag);
  const gdcm::ByteValue* bv = de.GetByteValue();
  if (bv == nullptr) return std::nullopt;
  std::string s(bv->GetPointer(), bv->GetLength());
  while (!s.empty() && (s.back() == ' ' || s.back() == '\0'))
    s.pop_back();
  std::size_t start = 0;
  while (start < s.size() && s[start] == ' ')
    ++start;
  return s.substr(start);
}

// A DS (decimal string) value with `count` numbers separated by backslashes.
std::optional<std::vector<double>> numbers_of(const gdcm::DataSet& ds, const gdcm::Tag& tag,
                                              std::size_t count) {
  const auto s = text_of(ds, tag);
  if (!s) return std::nullopt;
  std::vector<double> out;
  std::size_t pos = 0;
  while (pos <= s->size()) {
    std::size_t end = s->find('\\', pos);
    if (end == std::string::npos) end = s->size();
    std::string_view part(s->data() + pos, end - pos);
    while (!part.empty() && part.front() == ' ')
      part.remove_prefix(1);
    while (!part.empty() && part.back() == ' ')
      part.remove_suffix(1);
    if (!part.empty() && part.front() == '+') part.remove_prefix(1);
    double v = 0.0;
    const auto r = std::from_chars(part.data(), part.data() + part.size(), v);
    if (r.ec != std::errc() || r.ptr != part.data() + part.size() || !std::isfinite(v)) {
      return std::nullopt;
    }
    out.push_back(v);
    pos = end + 1;
  }
  if (out.size() != count) return std::nullopt;
  return out;
}

template <std::uint16_t G, std::uint16_t E>
std::optional<unsigned> us_of(const gdcm::DataSet& ds) {
  const gdcm::Tag tag(G, E);
  if (!ds.FindDataElement(tag) || ds.GetDataElement(tag).IsEmpty()) return std::nullopt;
  gdcm::Attribute<G, E> a;
  a.SetFromDataElement(ds.GetDataElement(tag));
  return static_cast<unsigned>(a.GetValue());
}

struct Slice {
  std::filesystem::path file;
  std::string series;
  std::string modality;
  unsigned rows = 0;
  unsigned columns = 0;
  glm::dvec3 position{0.0};
  glm::dvec3 row_dir{0.0};        // +i (along a row: increasing column index)
  glm::dvec3 col_dir{0.0};        // +j
  glm::dvec2 pixel_spacing{0.0};  // (between columns = along i, between rows = along j)
  double slope = 1.0;
  double intercept = 0.0;
  double thickness = 0.0;
  double along_normal = 0.0;
};

// The header of one file; nullopt when it is not an image slice (no pixel data or no geometry).
std::optional<Slice> read_slice_header(const std::filesystem::path& file) {
  gdcm::Reader reader;
  reader.SetFileName(file.string().c_str());
  if (!reader.ReadUpToTag(gdcm::Tag(0x7fe0, 0x0010))) return std::nullopt;
  const gdcm::DataSet& ds = reader.GetFile().GetDataSet();
  const std::string name = file.string();
  const auto rows = us_of<0x0028, 0x0010>(ds);
  const auto columns = us_of<0x0028, 0x0011>(ds);
  if (!rows || !columns) return std::nullopt;  // not an image
  Slice s;
  s.file = file;
  s.rows = *rows;
  s.columns = *columns;
  s.series = text_of(ds, gdcm::Tag(0x0020, 0x000e)).value_or("");
  s.modality = text_of(ds, gdcm::Tag(0x0008, 0x0060)).value_or("");
  const auto frames = text_of(ds, gdcm::Tag(0x0028, 0x0008));
  if (frames && !frames->empty() && *frames != "1") {
    throw InputError(cat(name, ": multi-frame images (", *frames, " frames) are not supported"));
  }
  const auto spp = us_of<0x0028, 0x0002>(ds);
  if (spp && *spp != 1) {
    throw InputError(cat(name, ": ", *spp, " samples per pixel (colour) is not supported"));
  }
  const auto ipp = numbers_of(ds, gdcm::Tag(0x0020, 0x0032), 3);
  const auto iop = numbers_of(ds, gdcm::Tag(0x0020, 0x0037), 6);
  if (!ipp) throw InputError(cat(name, ": no valid ImagePositionPatient (0020,0032)"));
  if (!iop) throw InputError(cat(name, ": no valid ImageOrientationPatient (0020,0037)"));
  s.position = {(*ipp)[0], (*ipp)[1], (*ipp)[2]};
  s.row_dir = {(*iop)[0], (*iop)[1], (*iop)[2]};
  s.col_dir = {(*iop)[3], (*iop)[4], (*iop)[5]};
  const auto ps = numbers_of(ds, gdcm::Tag(0x0028, 0x0030), 2);
  if (!ps) throw InputError(cat(name, ": no valid PixelSpacing (0028,0030)"));
  // PixelSpacing is (row spacing, column spacing): the distance between rows is the step of j.
  s.pixel_spacing = {(*ps)[1], (*ps)[0]};
  for (int a = 0; a < 2; ++a) {
    if (!(s.pixel_spacing[a] > 0.0)) {
      throw InputError(
          cat(name, ": PixelSpacing ", (*ps)[0], "\\", (*ps)[1], ": spacing must be positive"));
    }
  }
  if (const auto slope = numbers_of(ds, gdcm::Tag(0x0028, 0x1053), 1)) s.slope = (*slope)[0];
  if (const auto inter = numbers_of(ds, gdcm::Tag(0x0028, 0x1052), 1)) s.intercept = (*inter)[0];
  if (s.slope == 0.0) throw InputError(cat(name, ": RescaleSlope is 0"));
  if (const auto t = numbers_of(ds, gdcm::Tag(0x0018, 0x0050), 1)) s.thickness = (*t)[0];
  if (const auto t = numbers_of(ds, gdcm::Tag(0x0018, 0x0088), 1)) s.thickness = (*t)[0];
  return s;
}

std::string short_name(const std::filesystem::path& p) {
  return p.filename().string();
}

}  // namespace

VolumeFile read_dicom_folder(const std::filesystem::path& dir, const VolumeReadOptions& options) {
  const std::string dir_name = dir.string();
  const ErrorSite site(dir_name);
  std::vector<std::filesystem::path> files;
  {
    std::error_code ec;
    std::filesystem::directory_iterator it(dir, ec);
    if (ec) site.whole(cat("cannot list the folder: ", ec.message()));
    for (; it != std::filesystem::directory_iterator(); it.increment(ec)) {
      if (ec) site.whole(cat("cannot list the folder: ", ec.message()));
      std::error_code fec;
      if (it->is_regular_file(fec)) files.push_back(it->path());
    }
  }
  std::sort(files.begin(), files.end());
  const std::size_t total_work = 2 * files.size();
  std::size_t work = 0;

  // Pass 1: headers.
  std::map<std::string, std::vector<Slice>> series;
  for (const auto& f : files) {
    if (auto s = read_slice_header(f)) series[s->series].push_back(std::move(*s));
    if (options.progress) options.progress(++work, total_work);
  }
  if (series.empty()) {
    site.whole(cat("no DICOM image slices in the folder (", files.size(), " files)"));
  }
  std::vector<Slice>* chosen = nullptr;
  if (!options.series_uid.empty()) {
    const auto it = series.find(options.series_uid);
    if (it == series.end())
      site.whole(cat("no series with SeriesInstanceUID ", options.series_uid));
    chosen = &it->second;
  } else if (series.size() > 1) {
    std::string list;
    for (const auto& [uid, slices] : series) {
      list += cat("\n  ", uid.empty() ? "(no SeriesInstanceUID)" : uid, ": ", slices.size(),
                  " slices, e.g. ", short_name(slices.front().file));
    }
    site.whole(
        cat(series.size(), " series in the folder; pick one by its SeriesInstanceUID:", list));
  } else {
    chosen = &series.begin()->second;
  }
  std::vector<Slice>& slices = *chosen;

  // Geometry of the first slice; every other must agree.
  const Slice& first = slices.front();
  const ErrorSite first_site(first.file.string());
  glm::dmat3 dir3;
  {
    const double lr = glm::length(first.row_dir), lc = glm::length(first.col_dir);
    if (!(std::abs(lr - 1.0) < 1e-3) || !(std::abs(lc - 1.0) < 1e-3)) {
      first_site.whole("ImageOrientationPatient rows are not unit vectors");
    }
    glm::dmat3 raw(first.row_dir / lr, first.col_dir / lc, glm::dvec3(0.0));
    raw[2] = glm::normalize(glm::cross(raw[0], raw[1]));
    dir3 = orthonormalized(raw, first_site);
  }
  const glm::dvec3 normal = dir3[2];
  for (Slice& s : slices) {
    const std::string sname = s.file.string();
    if (s.rows != first.rows || s.columns != first.columns) {
      throw InputError(cat(sname, ": slice size ", s.columns, " x ", s.rows, " differs from ",
                           first.columns, " x ", first.rows, " of ", short_name(first.file)));
    }
    if (std::abs(s.pixel_spacing.x - first.pixel_spacing.x) > 1e-4 * first.pixel_spacing.x ||
        std::abs(s.pixel_spacing.y - first.pixel_spacing.y) > 1e-4 * first.pixel_spacing.y) {
      throw InputError(cat(sname, ": pixel spacing ", s.pixel_spacing.y, "\\", s.pixel_spacing.x,
                           " differs from ", first.pixel_spacing.y, "\\", first.pixel_spacing.x,
                           " of ", short_name(first.file)));
    }
    if (glm::length(s.row_dir - first.row_dir) > 1e-4 ||
        glm::length(s.col_dir - first.col_dir) > 1e-4) {
      throw InputError(
          cat(sname, ": image orientation differs from that of ", short_name(first.file)));
    }
    s.along_normal = glm::dot(s.position, normal);
  }
  std::stable_sort(slices.begin(), slices.end(),
                   [](const Slice& a, const Slice& b) { return a.along_normal < b.along_normal; });

  // Slice spacing: uniform; a gap of about k spacings is k - 1 missing slices.
  double spacing = first.thickness > 0.0 ? first.thickness : 1.0;
  const std::size_t n = slices.size();
  if (n > 1) {
    std::vector<double> gaps;
    for (std::size_t k = 1; k < n; ++k) {
      const double gap = slices[k].along_normal - slices[k - 1].along_normal;
      if (gap < 1e-6) {
        throw InputError(cat(slices[k].file.string(), ": same slice position as ",
                             short_name(slices[k - 1].file), " (duplicate slice)"));
      }
      gaps.push_back(gap);
    }
    std::vector<double> sorted = gaps;
    std::nth_element(sorted.begin(),
                     sorted.begin() + static_cast<std::ptrdiff_t>(sorted.size() / 2), sorted.end());
    const double nominal = sorted[sorted.size() / 2];
    const double tolerance = 0.01 * nominal + 1e-3;
    for (std::size_t k = 1; k < n; ++k) {
      const double gap = gaps[k - 1];
      if (std::abs(gap - nominal) <= tolerance) continue;
      const double ratio = gap / nominal;
      if (ratio > 1.5 && std::abs(ratio - std::round(ratio)) < 0.1) {
        const auto missing = static_cast<long>(std::lround(ratio)) - 1;
        site.whole(cat("missing slice", missing > 1 ? "s" : "", ": a gap of ", gap, " mm (about ",
                       missing, " slice", missing > 1 ? "s" : "", ") between ",
                       slices[k - 1].file.string(), " and ", slices[k].file.string(),
                       " where the slice spacing is ", nominal, " mm"));
      }
      site.whole(cat("non-uniform slice spacing: ", gap, " mm between ",
                     slices[k - 1].file.string(), " and ", slices[k].file.string(),
                     " where the spacing is ", nominal, " mm"));
    }
    spacing =
        (slices.back().along_normal - slices.front().along_normal) / static_cast<double>(n - 1);
    // Every position on the line through the first along the normal (no gantry tilt / shear).
    for (const Slice& s : slices) {
      const glm::dvec3 d = s.position - slices.front().position;
      const glm::dvec3 off = d - glm::dot(d, normal) * normal;
      if (glm::length(off) > 1e-2 + 1e-3 * glm::length(d)) {
        throw InputError(cat(s.file.string(), ": slice position is off the slice normal by ",
                             glm::length(off), " mm (tilted or sheared series not supported)"));
      }
    }
  }

  VolumeFile out;
  out.format = VolumeFormat::DicomSeries;
  Volume& vol = out.volume;
  vol.source = dir_name;
  vol.modality = first.modality;
  VolumeGeometry& g = vol.geometry;
  g.dims = {static_cast<std::int64_t>(first.columns), static_cast<std::int64_t>(first.rows),
            static_cast<std::int64_t>(n)};
  g.spacing = {first.pixel_spacing.x, first.pixel_spacing.y, spacing};
  g.direction = dir3;
  g.origin = slices.front().position;
  const SampleCount count = checked_count(g.dims, SampleType::Float32, site);
  if (work < files.size()) work = files.size();
  // Pass 2: pixels.
  vol.values.resize(count.samples);
  const std::size_t per_slice = static_cast<std::size_t>(first.columns) * first.rows;
  std::vector<char> buffer;
  std::string stored;
  for (std::size_t k = 0; k < n; ++k) {
    const Slice& s = slices[k];
    const std::string sname = s.file.string();
    gdcm::ImageReader reader;
    reader.SetFileName(sname.c_str());
    if (!reader.Read()) throw InputError(cat(sname, ": cannot read the pixel data"));
    const gdcm::Image& image = reader.GetImage();
    const unsigned* d = image.GetDimensions();
    if (d == nullptr || d[0] != s.columns || d[1] != s.rows ||
        (image.GetNumberOfDimensions() > 2 && d[2] != 1)) {
      throw InputError(cat(sname, ": the pixel data does not match Rows x Columns"));
    }
    const gdcm::PixelFormat pf = image.GetPixelFormat();
    SampleType type = SampleType::UInt8;
    switch (pf.GetScalarType()) {
      case gdcm::PixelFormat::UINT8:
        type = SampleType::UInt8;
        break;
      case gdcm::PixelFormat::INT8:
        type = SampleType::Int8;
        break;
      case gdcm::PixelFormat::UINT12:
      case gdcm::PixelFormat::UINT16:
        type = SampleType::UInt16;
        break;
      case gdcm::PixelFormat::INT12:
      case gdcm::PixelFormat::INT16:
        type = SampleType::Int16;
        break;
      case gdcm::PixelFormat::UINT32:
        type = SampleType::UInt32;
        break;
      case gdcm::PixelFormat::INT32:
        type = SampleType::Int32;
        break;
      case gdcm::PixelFormat::UINT64:
        type = SampleType::UInt64;
        break;
      case gdcm::PixelFormat::INT64:
        type = SampleType::Int64;
        break;
      case gdcm::PixelFormat::FLOAT32:
        type = SampleType::Float32;
        break;
      case gdcm::PixelFormat::FLOAT64:
        type = SampleType::Float64;
        break;
      default:
        throw InputError(cat(sname, ": unsupported pixel format ", pf.GetScalarTypeAsString()));
    }
    if (pf.GetSamplesPerPixel() != 1) {
      throw InputError(cat(sname, ": ", pf.GetSamplesPerPixel(),
                           " samples per pixel (colour) is not supported"));
    }
    if (stored.empty()) stored = type_name(type);
    const std::size_t need = per_slice * sample_size(type);
    const unsigned long length = image.GetBufferLength();
    if (length < need) {
      throw InputError(
          cat(sname, ": truncated pixel data: ", length, " bytes, Rows x Columns needs ", need));
    }
    buffer.resize(length);
    if (!image.GetBuffer(buffer.data()))
      throw InputError(cat(sname, ": cannot decode the pixel data"));
    Rescale rescale;
    if (s.slope != 1.0 || s.intercept != 0.0) {
      rescale = {true, s.slope, s.intercept};
      out.rescaled = true;
    }
    convert_samples(reinterpret_cast<const std::byte*>(buffer.data()), per_slice, type, false,
                    rescale, vol.values.data() + k * per_slice);
    if (options.progress) options.progress(++work, total_work);
  }
  out.stored_type = stored;
  if (options.progress) options.progress(total_work, total_work);
  return out;
}

}  // namespace bisturi::volume_io
