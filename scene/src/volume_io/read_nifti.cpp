// NIfTI-1 single files (magic "n+1"), plain or gzip-compressed: the 348-byte header, an optional
// extension block, the samples at vox_offset.

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstring>
#include <optional>

#include "readers.h"
#include "volume_common.h"

namespace bisturi::volume_io {

namespace {

constexpr std::size_t kHeaderSize = 348;

class HeaderView {
 public:
  HeaderView(const std::byte* h, bool swap) : h_(h), swap_(swap) {}

  template <class T>
  T get(std::size_t offset) const {
    using U = std::conditional_t<sizeof(T) == 2, std::uint16_t, std::uint32_t>;
    U u;
    std::memcpy(&u, h_ + offset, sizeof u);
    if (swap_) {
      if constexpr (sizeof(T) == 2) {
        u = __builtin_bswap16(u);
      } else {
        u = __builtin_bswap32(u);
      }
    }
    return std::bit_cast<T>(u);
  }
  std::int16_t i16(std::size_t offset) const { return get<std::int16_t>(offset); }
  std::int32_t i32(std::size_t offset) const { return get<std::int32_t>(offset); }
  double f32(std::size_t offset) const { return static_cast<double>(get<float>(offset)); }
  unsigned char u8(std::size_t offset) const { return static_cast<unsigned char>(h_[offset]); }

 private:
  const std::byte* h_;
  bool swap_;
};

std::optional<SampleType> nifti_type(int code) {
  switch (code) {
    case 2:
      return SampleType::UInt8;
    case 4:
      return SampleType::Int16;
    case 8:
      return SampleType::Int32;
    case 16:
      return SampleType::Float32;
    case 64:
      return SampleType::Float64;
    case 256:
      return SampleType::Int8;
    case 512:
      return SampleType::UInt16;
    case 768:
      return SampleType::UInt32;
    case 1024:
      return SampleType::Int64;
    case 1280:
      return SampleType::UInt64;
    default:
      return std::nullopt;
  }
}

const char* nifti_type_name(int code) {
  switch (code) {
    case 0:
      return "unknown";
    case 1:
      return "binary";
    case 32:
      return "complex64";
    case 128:
      return "rgb24";
    case 1536:
      return "float128";
    case 1792:
      return "complex128";
    case 2048:
      return "complex256";
    case 2304:
      return "rgba32";
    default:
      return "not a NIfTI-1 type";
  }
}

struct Layout {
  SampleType type = SampleType::UInt8;
  SampleCount count;
  std::size_t data_offset = 0;
  bool big_endian = false;
  Rescale rescale;
};

// Checks the header and sets everything but the values; returns where the samples are.
Layout interpret_header(const std::byte* h, const ErrorSite& site, VolumeFile& out) {
  std::int32_t sizeof_hdr = 0;
  std::memcpy(&sizeof_hdr, h, 4);
  bool swap = false;
  if (sizeof_hdr == 348) {
    swap = false;
  } else if (static_cast<std::int32_t>(__builtin_bswap32(static_cast<std::uint32_t>(sizeof_hdr))) ==
             348) {
    swap = true;
  } else if (sizeof_hdr == 540 || static_cast<std::int32_t>(__builtin_bswap32(
                                      static_cast<std::uint32_t>(sizeof_hdr))) == 540) {
    site.at_byte(0, "NIfTI-2 files are not supported (sizeof_hdr 540)");
  } else {
    site.at_byte(0, cat("not a NIfTI-1 file (sizeof_hdr is ", sizeof_hdr, ", expected 348)"));
  }
  const HeaderView v(h, swap);
  const bool big_endian_data = (std::endian::native == std::endian::big) != swap;
  if (std::memcmp(h + 344, "ni1\0", 4) == 0) {
    site.at_byte(344, "a NIfTI-1 header with separate data (.hdr/.img pair) is not supported");
  }
  if (std::memcmp(h + 344, "n+1\0", 4) != 0) {
    site.at_byte(344, "bad NIfTI-1 magic (expected 'n+1')");
  }

  // Dimensions.
  const int ndim = v.i16(40);
  std::array<std::int64_t, 3> dims{};
  for (std::size_t a = 0; a < 3; ++a)
    dims[a] = v.i16(42 + 2 * a);
  if (ndim == 4) {
    if (v.i16(48) != 1) {
      site.at_byte(48, cat("only 3-D volumes are read (dim[0] 4 with dim[4] ", v.i16(48), ")"));
    }
  } else if (ndim != 3) {
    site.at_byte(40, cat("only 3-D volumes are read (dim[0] is ", ndim, ")"));
  }
  const int code = v.i16(70);
  const auto type = nifti_type(code);
  if (!type) {
    site.at_byte(70, cat("unsupported datatype ", code, " (", nifti_type_name(code), ")"));
  }
  const int bitpix = v.i16(72);
  if (bitpix != static_cast<int>(8 * sample_size(*type))) {
    site.at_byte(
        72, cat("bitpix ", bitpix, " does not match datatype ", code, " (", type_name(*type), ")"));
  }
  const SampleCount count = checked_count(dims, *type, site);
  out.volume.geometry.dims = dims;
  out.stored_type = type_name(*type);

  // Units and spacing.
  double unit = 1.0;
  switch (v.u8(123) & 0x07) {
    case 0:  // unknown: millimetres assumed
    case 2:
      unit = 1.0;
      break;
    case 1:
      unit = 1000.0;
      break;
    case 3:
      unit = 0.001;
      break;
    default:
      site.at_byte(123, cat("unknown spatial unit code ", v.u8(123) & 0x07));
  }
  glm::dvec3 pixdim;
  for (int a = 0; a < 3; ++a) {
    pixdim[a] = v.f32(80 + 4 * static_cast<std::size_t>(a));
  }

  const int qform_code = v.i16(252);
  const int sform_code = v.i16(254);
  glm::dmat3 steps(1.0);
  glm::dvec3 origin(0.0);
  if (sform_code > 0) {
    for (int r = 0; r < 3; ++r) {
      const std::size_t row = 280 + 16 * static_cast<std::size_t>(r);
      for (int c = 0; c < 3; ++c)
        steps[c][r] = v.f32(row + 4 * static_cast<std::size_t>(c));
      origin[r] = v.f32(row + 12);
    }
  } else {
    for (int a = 0; a < 3; ++a) {
      if (!(pixdim[a] > 0.0) || !std::isfinite(pixdim[a])) {
        site.at_byte(80 + 4 * static_cast<std::size_t>(a),
                     cat("pixdim[", a + 1, "] is ", pixdim[a],
                         ": spacing must be a positive finite number"));
      }
    }
    if (qform_code > 0) {
      const double b = v.f32(256), c = v.f32(260), d = v.f32(264);
      if (!std::isfinite(b) || !std::isfinite(c) || !std::isfinite(d)) {
        site.at_byte(256, "the qform quaternion is not finite");
      }
      const double aa = 1.0 - (b * b + c * c + d * d);
      if (aa < -1e-5) site.at_byte(256, "the qform quaternion (b, c, d) is longer than 1");
      const double a = aa > 0.0 ? std::sqrt(aa) : 0.0;
      glm::dmat3 r;  // columns
      r[0] = {a * a + b * b - c * c - d * d, 2 * (b * c + a * d), 2 * (b * d - a * c)};
      r[1] = {2 * (b * c - a * d), a * a + c * c - b * b - d * d, 2 * (c * d + a * b)};
      r[2] = {2 * (b * d + a * c), 2 * (c * d - a * b), a * a + d * d - c * c - b * b};
      const double qfac = v.f32(76) < 0.0 ? -1.0 : 1.0;
      steps[0] = r[0] * pixdim[0];
      steps[1] = r[1] * pixdim[1];
      steps[2] = r[2] * (qfac * pixdim[2]);
      origin = {v.f32(268), v.f32(272), v.f32(276)};
    } else {
      steps = glm::dmat3(1.0);
      for (int a = 0; a < 3; ++a)
        steps[a][a] = pixdim[a];
    }
  }
  // RAS -> LPS: negate x and y of every world vector.
  const glm::dvec3 flip(-1.0, -1.0, 1.0);
  for (int a = 0; a < 3; ++a)
    steps[a] = steps[a] * flip * unit;
  origin = origin * flip * unit;
  set_geometry_from_steps(out.volume.geometry, steps, origin, site);

  // Rescale.
  const double slope = v.f32(112);
  const double inter = v.f32(116);
  Rescale rescale;
  if (slope != 0.0 && std::isfinite(slope)) {
    if (!std::isfinite(inter)) site.at_byte(116, "scl_inter is not finite");
    if (slope != 1.0 || inter != 0.0) rescale = {true, slope, inter};
  }
  out.rescaled = rescale.apply;

  // Where the samples are.
  const double vox_offset = v.f32(108);
  if (!(vox_offset >= 0.0) || vox_offset > 1e15 || vox_offset != std::floor(vox_offset)) {
    site.at_byte(108, cat("bad vox_offset ", vox_offset));
  }
  const auto offset = static_cast<std::size_t>(vox_offset);
  if (offset < kHeaderSize + 4) {
    site.at_byte(108, cat("vox_offset ", offset, " points into the header (must be >= 352)"));
  }
  Layout layout;
  layout.type = *type;
  layout.count = count;
  layout.data_offset = offset;
  layout.big_endian = big_endian_data;
  layout.rescale = rescale;
  return layout;
}

}  // namespace

VolumeFile parse_nifti(std::span<const std::byte> data, const std::string& name,
                       const VolumeReadOptions& options) {
  const ErrorSite site(name);
  VolumeFile out;
  out.format = VolumeFormat::Nifti;
  out.volume.source = name;
  const bool gzip = data.size() >= 2 && static_cast<unsigned char>(data[0]) == 0x1f &&
                    static_cast<unsigned char>(data[1]) == 0x8b;
  if (!gzip) {
    if (data.size() < kHeaderSize) {
      site.at_byte(data.size(),
                   cat("truncated header: ", data.size(), " bytes, a NIfTI-1 header has 348"));
    }
    const Layout l = interpret_header(data.data(), site, out);
    if (l.data_offset > data.size() || data.size() - l.data_offset < l.count.bytes) {
      site.at_byte(
          std::min(l.data_offset, data.size()),
          cat("truncated data: ", data.size() - std::min(l.data_offset, data.size()),
              " bytes after vox_offset ", l.data_offset, ", the header needs ", l.count.bytes));
    }
    out.volume.values.resize(l.count.samples);
    convert_samples(data.data() + l.data_offset, l.count.samples, l.type, l.big_endian, l.rescale,
                    out.volume.values.data(), options.progress, 0, l.count.bytes);
    if (options.progress && l.count.bytes == 0) options.progress(0, 0);
    return out;
  }
  Inflater inflater(data, site);
  std::array<std::byte, kHeaderSize> header{};
  const std::size_t got = inflater.read(header);
  if (got != kHeaderSize) {
    site.whole(
        cat("truncated header: the gzip data holds ", got, " bytes, a NIfTI-1 header has 348"));
  }
  const Layout l = interpret_header(header.data(), site, out);
  const std::size_t need = l.data_offset - kHeaderSize + l.count.bytes;
  if (l.data_offset + l.count.bytes > max_inflated_size(data.size())) {
    site.whole(cat("truncated data: ", data.size(), " compressed bytes cannot hold the ",
                   l.data_offset + l.count.bytes, " bytes the header needs"));
  }
  BigVector<std::byte> rest(need);
  const std::size_t got_rest = inflater.read(rest);
  if (got_rest != need) {
    site.whole(cat("truncated data: the gzip data holds ", kHeaderSize + got_rest,
                   " bytes, the header needs ", l.data_offset + l.count.bytes, " (vox_offset ",
                   l.data_offset, " + ", l.count.bytes, " bytes of samples)"));
  }
  out.volume.values.resize(l.count.samples);
  convert_samples(rest.data() + (l.data_offset - kHeaderSize), l.count.samples, l.type,
                  l.big_endian, l.rescale, out.volume.values.data(), options.progress, 0,
                  l.count.bytes);
  if (options.progress && l.count.bytes == 0) options.progress(0, 0);
  return out;
}

}  // namespace bisturi::volume_io

namespace bisturi {

Volume read_nifti_from_memory(std::span<const std::byte> data, const std::string& name_for_errors,
                              const VolumeReadOptions& options) {
  return volume_io::parse_nifti(data, name_for_errors, options).volume;
}

}  // namespace bisturi
