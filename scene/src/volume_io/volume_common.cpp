#include "volume_common.h"

#include <zlib.h>

#include <algorithm>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <new>

#include "bisturi/scene/errors.h"

namespace bisturi::volume_io {

std::size_t sample_size(SampleType type) {
  switch (type) {
    case SampleType::Int8:
    case SampleType::UInt8:
      return 1;
    case SampleType::Int16:
    case SampleType::UInt16:
      return 2;
    case SampleType::Int32:
    case SampleType::UInt32:
    case SampleType::Float32:
      return 4;
    case SampleType::Int64:
    case SampleType::UInt64:
    case SampleType::Float64:
      return 8;
  }
  return 1;
}

const char* type_name(SampleType type) {
  switch (type) {
    case SampleType::Int8:
      return "int8";
    case SampleType::UInt8:
      return "uint8";
    case SampleType::Int16:
      return "int16";
    case SampleType::UInt16:
      return "uint16";
    case SampleType::Int32:
      return "int32";
    case SampleType::UInt32:
      return "uint32";
    case SampleType::Int64:
      return "int64";
    case SampleType::UInt64:
      return "uint64";
    case SampleType::Float32:
      return "float32";
    case SampleType::Float64:
      return "float64";
  }
  return "?";
}

SampleCount checked_count(const std::array<std::int64_t, 3>& dims, SampleType type,
                          const ErrorSite& site) {
  constexpr std::size_t kMax = std::numeric_limits<std::size_t>::max();
  std::size_t n = 1;
  for (int a = 0; a < 3; ++a) {
    if (dims[static_cast<std::size_t>(a)] < 1) {
      site.whole(cat("size ", dims[static_cast<std::size_t>(a)], " along axis ", a,
                     " (every size must be at least 1)"));
    }
    const auto d = static_cast<std::size_t>(dims[static_cast<std::size_t>(a)]);
    if (n > kMax / d)
      site.whole(cat("sizes ", dims[0], " x ", dims[1], " x ", dims[2], " overflow"));
    n *= d;
  }
  const std::size_t s = sample_size(type);
  // Leave room for the float copy too (4 bytes a sample) and for offsets added to the size.
  if (n > (kMax / 16) / std::max<std::size_t>(s, 4)) {
    site.whole(cat("sizes ", dims[0], " x ", dims[1], " x ", dims[2], " overflow"));
  }
  return {n, n * s};
}

namespace {

template <class T>
T load(const std::byte* p, bool swap) {
  if constexpr (sizeof(T) == 1) {
    T v;
    std::memcpy(&v, p, 1);
    return v;
  } else {
    using U = std::conditional_t<sizeof(T) == 2, std::uint16_t,
                                 std::conditional_t<sizeof(T) == 4, std::uint32_t, std::uint64_t>>;
    U u;
    std::memcpy(&u, p, sizeof u);
    if (swap) {
      if constexpr (sizeof(T) == 2) {
        u = __builtin_bswap16(u);
      } else if constexpr (sizeof(T) == 4) {
        u = __builtin_bswap32(u);
      } else {
        u = __builtin_bswap64(u);
      }
    }
    return std::bit_cast<T>(u);
  }
}

template <class T>
void convert_block(const std::byte* src, std::size_t count, bool swap, const Rescale& rescale,
                   float* dst) {
  if (rescale.apply) {
    for (std::size_t n = 0; n < count; ++n) {
      const double v = static_cast<double>(load<T>(src + n * sizeof(T), swap));
      dst[n] = static_cast<float>(rescale.slope * v + rescale.intercept);
    }
  } else {
    for (std::size_t n = 0; n < count; ++n) {
      dst[n] = static_cast<float>(load<T>(src + n * sizeof(T), swap));
    }
  }
}

}  // namespace

void convert_samples(const std::byte* src, std::size_t count, SampleType type, bool big_endian,
                     const Rescale& rescale, float* dst,
                     const std::function<void(std::size_t, std::size_t)>& progress,
                     std::size_t done_before, std::size_t total) {
  const bool swap = big_endian != (std::endian::native == std::endian::big);
  const std::size_t size = sample_size(type);
  constexpr std::size_t kBlockBytes = std::size_t{16} << 20;
  const std::size_t block = kBlockBytes / size;
  for (std::size_t first = 0; first < count; first += block) {
    const std::size_t n = std::min(block, count - first);
    const std::byte* s = src + first * size;
    float* d = dst + first;
    switch (type) {
      case SampleType::Int8:
        convert_block<std::int8_t>(s, n, swap, rescale, d);
        break;
      case SampleType::UInt8:
        convert_block<std::uint8_t>(s, n, swap, rescale, d);
        break;
      case SampleType::Int16:
        convert_block<std::int16_t>(s, n, swap, rescale, d);
        break;
      case SampleType::UInt16:
        convert_block<std::uint16_t>(s, n, swap, rescale, d);
        break;
      case SampleType::Int32:
        convert_block<std::int32_t>(s, n, swap, rescale, d);
        break;
      case SampleType::UInt32:
        convert_block<std::uint32_t>(s, n, swap, rescale, d);
        break;
      case SampleType::Int64:
        convert_block<std::int64_t>(s, n, swap, rescale, d);
        break;
      case SampleType::UInt64:
        convert_block<std::uint64_t>(s, n, swap, rescale, d);
        break;
      case SampleType::Float32:
        convert_block<float>(s, n, swap, rescale, d);
        break;
      case SampleType::Float64:
        convert_block<double>(s, n, swap, rescale, d);
        break;
    }
    if (progress) progress(done_before + (first + n) * size, total);
  }
}

glm::dmat3 orthonormalized(const glm::dmat3& direction, const ErrorSite& site) {
  constexpr double kTolerance = 1e-3;
  for (int a = 0; a < 3; ++a) {
    for (int b = a + 1; b < 3; ++b) {
      const double d = glm::dot(direction[a], direction[b]);
      if (!(std::abs(d) <= kTolerance)) {
        site.whole(cat("index axes ", a, " and ", b, " are not orthogonal (cosine ", d,
                       "): sheared grids are not supported"));
      }
    }
  }
  glm::dmat3 out;
  out[0] = glm::normalize(direction[0]);
  out[1] = glm::normalize(direction[1] - glm::dot(direction[1], out[0]) * out[0]);
  glm::dvec3 c = direction[2] - glm::dot(direction[2], out[0]) * out[0];
  c -= glm::dot(c, out[1]) * out[1];
  out[2] = glm::normalize(c);
  return out;
}

void set_geometry_from_steps(VolumeGeometry& geometry, const glm::dmat3& steps,
                             const glm::dvec3& origin, const ErrorSite& site) {
  glm::dmat3 unit;
  for (int a = 0; a < 3; ++a) {
    const glm::dvec3 s = steps[a];
    if (!std::isfinite(s.x) || !std::isfinite(s.y) || !std::isfinite(s.z)) {
      site.whole(cat("the world step of index axis ", a, " is not finite"));
    }
    const double len = glm::length(s);
    if (!(len > 0.0) || !std::isfinite(len)) {
      site.whole(cat("zero spacing along index axis ", a));
    }
    geometry.spacing[a] = len;
    unit[a] = s / len;
  }
  if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z)) {
    site.whole("the origin is not finite");
  }
  geometry.direction = orthonormalized(unit, site);
  geometry.origin = origin;
  // No negative zeros from axis flips (x + 0.0 is +0 for x = -0).
  for (int a = 0; a < 3; ++a) {
    geometry.origin[a] += 0.0;
    geometry.direction[a] += glm::dvec3(0.0);
  }
}

struct Inflater::State {
  z_stream z{};
};

Inflater::Inflater(std::span<const std::byte> input, const ErrorSite& site)
    : state_(new State), site_(site) {
  state_->z.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(input.data()));
  state_->z.avail_in = 0;
  if (inflateInit2(&state_->z, 15 + 32) != Z_OK) {
    delete state_;
    throw std::bad_alloc();
  }
  // avail_in is 32-bit: feed the input in pieces below 1 GiB.
  remaining_ = input.size();
  refill();
}

Inflater::~Inflater() {
  inflateEnd(&state_->z);
  delete state_;
}

void Inflater::refill() {
  if (state_->z.avail_in == 0 && remaining_ > 0) {
    const std::size_t n = std::min<std::size_t>(remaining_, std::size_t{1} << 30);
    state_->z.avail_in = static_cast<uInt>(n);
    remaining_ -= n;
  }
}

std::size_t Inflater::consumed() const {
  return static_cast<std::size_t>(state_->z.total_in);
}

std::size_t Inflater::read(std::span<std::byte> out) {
  z_stream& z = state_->z;
  std::size_t done = 0;
  while (done < out.size() && !ended_) {
    refill();
    const std::size_t want = std::min<std::size_t>(out.size() - done, std::size_t{1} << 30);
    z.next_out = reinterpret_cast<Bytef*>(out.data() + done);
    z.avail_out = static_cast<uInt>(want);
    const int rc = inflate(&z, Z_NO_FLUSH);
    done += want - z.avail_out;
    if (rc == Z_STREAM_END) {
      // Another gzip member may follow.
      refill();
      if (z.avail_in >= 2 && static_cast<unsigned char>(z.next_in[0]) == 0x1f &&
          static_cast<unsigned char>(z.next_in[1]) == 0x8b) {
        if (inflateReset(&z) != Z_OK) site_.whole("compressed data: cannot restart inflate");
        continue;
      }
      ended_ = true;
    } else if (rc == Z_BUF_ERROR) {
      if (z.avail_in == 0 && remaining_ == 0) {
        site_.whole(cat("compressed data ends early (truncated) after ", consumed(), " bytes"));
      }
    } else if (rc != Z_OK) {
      site_.whole(cat("compressed data is corrupt after ", consumed(),
                      " bytes: ", z.msg != nullptr ? z.msg : "inflate failed"));
    }
  }
  return done;
}

std::size_t max_inflated_size(std::size_t compressed) {
  constexpr std::size_t kRatio = 1032;
  if (compressed > std::numeric_limits<std::size_t>::max() / (2 * kRatio)) {
    return std::numeric_limits<std::size_t>::max();
  }
  return compressed * kRatio + 1024;
}

std::string gzip_compress(std::string_view data, const std::string& file_for_errors) {
  z_stream z{};
  if (deflateInit2(&z, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK) {
    throw std::bad_alloc();
  }
  std::string out;
  std::size_t in_done = 0;
  int rc = Z_OK;
  while (rc != Z_STREAM_END) {
    if (z.avail_in == 0) {
      const std::size_t n = std::min<std::size_t>(data.size() - in_done, std::size_t{1} << 30);
      z.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data() + in_done));
      z.avail_in = static_cast<uInt>(n);
      in_done += n;
    }
    const std::size_t old = out.size();
    out.resize(old + (std::size_t{1} << 20));
    z.next_out = reinterpret_cast<Bytef*>(out.data() + old);
    z.avail_out = 1u << 20;
    rc = deflate(&z, in_done == data.size() ? Z_FINISH : Z_NO_FLUSH);
    out.resize(old + (std::size_t{1} << 20) - z.avail_out);
    if (rc != Z_OK && rc != Z_STREAM_END && rc != Z_BUF_ERROR) {
      deflateEnd(&z);
      throw SceneError(cat(file_for_errors, ": cannot compress: deflate failed"));
    }
  }
  deflateEnd(&z);
  return out;
}

bool ends_with_icase(std::string_view s, std::string_view suffix) {
  if (s.size() < suffix.size()) return false;
  for (std::size_t n = 0; n < suffix.size(); ++n) {
    if (std::tolower(static_cast<unsigned char>(s[s.size() - suffix.size() + n])) !=
        std::tolower(static_cast<unsigned char>(suffix[n]))) {
      return false;
    }
  }
  return true;
}

}  // namespace bisturi::volume_io
