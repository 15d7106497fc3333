// NRRD (teem's "nearly raw raster data"), versions NRRD0001..NRRD0005: a text header, then the
// samples raw, gzip-compressed or as ascii numbers, attached or in a detached data file.

#include <algorithm>
#include <cctype>
#include <charconv>
#include <cmath>
#include <cstring>
#include <map>
#include <optional>
#include <string_view>
#include <vector>

#include "../io/file_io.h"
#include "readers.h"
#include "volume_common.h"

namespace bisturi::volume_io {

namespace {

struct Field {
  std::string value;
  std::size_t line = 0;
};

std::string_view trim(std::string_view s) {
  while (!s.empty() && (s.front() == ' ' || s.front() == '\t'))
    s.remove_prefix(1);
  while (!s.empty() && (s.back() == ' ' || s.back() == '\t' || s.back() == '\r'))
    s.remove_suffix(1);
  return s;
}

std::string lower(std::string_view s) {
  std::string out(s);
  for (char& c : out)
    c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return out;
}

std::vector<std::string_view> words(std::string_view s) {
  std::vector<std::string_view> out;
  std::size_t n = 0;
  while (n < s.size()) {
    while (n < s.size() && (s[n] == ' ' || s[n] == '\t'))
      ++n;
    const std::size_t start = n;
    while (n < s.size() && s[n] != ' ' && s[n] != '\t')
      ++n;
    if (n > start) out.push_back(s.substr(start, n - start));
  }
  return out;
}

std::optional<double> to_double(std::string_view s) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  double v = 0.0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) {
    const std::string l = lower(s);
    if (l == "nan") return std::nan("");
    if (l == "inf") return HUGE_VAL;
    if (l == "-inf") return -HUGE_VAL;
    return std::nullopt;
  }
  return v;
}

std::optional<std::int64_t> to_int(std::string_view s) {
  if (!s.empty() && s.front() == '+') s.remove_prefix(1);
  std::int64_t v = 0;
  const auto r = std::from_chars(s.data(), s.data() + s.size(), v);
  if (r.ec != std::errc() || r.ptr != s.data() + s.size()) return std::nullopt;
  return v;
}

std::optional<SampleType> nrrd_type(std::string_view spelled) {
  // Every spelling teem accepts (nrrdTypeStr and its equivalents), spaces collapsed.
  std::string t;
  for (std::string_view w : words(spelled)) {
    if (!t.empty()) t += ' ';
    t += lower(w);
  }
  static const std::map<std::string, SampleType, std::less<>> kTypes = {
      {"signed char", SampleType::Int8},
      {"int8", SampleType::Int8},
      {"int8_t", SampleType::Int8},
      {"uchar", SampleType::UInt8},
      {"unsigned char", SampleType::UInt8},
      {"uint8", SampleType::UInt8},
      {"uint8_t", SampleType::UInt8},
      {"short", SampleType::Int16},
      {"short int", SampleType::Int16},
      {"signed short", SampleType::Int16},
      {"signed short int", SampleType::Int16},
      {"int16", SampleType::Int16},
      {"int16_t", SampleType::Int16},
      {"ushort", SampleType::UInt16},
      {"unsigned short", SampleType::UInt16},
      {"unsigned short int", SampleType::UInt16},
      {"uint16", SampleType::UInt16},
      {"uint16_t", SampleType::UInt16},
      {"int", SampleType::Int32},
      {"signed int", SampleType::Int32},
      {"int32", SampleType::Int32},
      {"int32_t", SampleType::Int32},
      {"uint", SampleType::UInt32},
      {"unsigned int", SampleType::UInt32},
      {"uint32", SampleType::UInt32},
      {"uint32_t", SampleType::UInt32},
      {"longlong", SampleType::Int64},
      {"long long", SampleType::Int64},
      {"long long int", SampleType::Int64},
      {"signed long long", SampleType::Int64},
      {"signed long long int", SampleType::Int64},
      {"int64", SampleType::Int64},
      {"int64_t", SampleType::Int64},
      {"ulonglong", SampleType::UInt64},
      {"unsigned long long", SampleType::UInt64},
      {"unsigned long long int", SampleType::UInt64},
      {"uint64", SampleType::UInt64},
      {"uint64_t", SampleType::UInt64},
      {"float", SampleType::Float32},
      {"double", SampleType::Float64},
  };
  const auto it = kTypes.find(t);
  if (it == kTypes.end()) return std::nullopt;
  return it->second;
}

enum class Encoding { Raw, Gzip, Ascii };

class NrrdParser {
 public:
  NrrdParser(std::span<const std::byte> data, const std::string& name,
             const VolumeReadOptions& options, const std::filesystem::path& data_dir)
      : data_(data), name_(name), site_(name_), options_(options), data_dir_(data_dir) {}

  VolumeFile parse() {
    read_header();
    VolumeFile out;
    out.format = VolumeFormat::Nrrd;
    out.volume.source = name_;
    interpret(out);
    out.volume.modality = modality_;
    read_samples(out);
    return out;
  }

 private:
  std::string_view text(std::size_t begin, std::size_t end) const {
    return {reinterpret_cast<const char*>(data_.data()) + begin, end - begin};
  }

  void read_header() {
    std::size_t pos = 0;
    std::size_t line = 0;
    bool blank = false;
    while (pos < data_.size()) {
      const auto* start = reinterpret_cast<const char*>(data_.data()) + pos;
      const void* nl = std::memchr(start, '\n', data_.size() - pos);
      const std::size_t end =
          nl != nullptr ? static_cast<std::size_t>(static_cast<const char*>(nl) -
                                                   reinterpret_cast<const char*>(data_.data()))
                        : data_.size();
      ++line;
      std::string_view l = text(pos, end);
      if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
      pos = nl != nullptr ? end + 1 : end;
      if (line == 1) {
        if (l.size() != 8 || l.substr(0, 7) != "NRRD000" || l[7] < '1' || l[7] > '9') {
          site_.at_line(1, cat("not a NRRD file (the first line is ", quote(l),
                               ", expected NRRD0001..NRRD0005)"));
        }
        continue;
      }
      if (l.empty()) {
        blank = true;
        break;
      }
      if (l.front() == '#') continue;
      const std::size_t kv = l.find(":=");
      if (kv != std::string_view::npos) {
        // Key/value pairs are free-form; only a modality (as write_nrrd stores it) is kept.
        if (trim(l.substr(0, kv)) == "modality") modality_ = std::string(trim(l.substr(kv + 2)));
        continue;
      }
      const std::size_t colon = l.find(": ");
      if (colon == std::string_view::npos) {
        site_.at_line(line, cat("expected 'field: value', got ", quote(l)));
      }
      std::string key = lower(trim(l.substr(0, colon)));
      // Older spellings.
      if (key == "centerings") key = "centers";
      if (key == "datafile") key = "data file";
      if (key == "lineskip") key = "line skip";
      if (key == "byteskip") key = "byte skip";
      if (!fields_.emplace(key, Field{std::string(trim(l.substr(colon + 2))), line}).second) {
        site_.at_line(line, cat("field ", quote(key), " given twice"));
      }
    }
    if (line == 0) site_.whole("empty file");
    header_end_ = pos;
    blank_line_ = blank;
  }

  const Field* field(std::string_view key) const {
    const auto it = fields_.find(std::string(key));
    return it == fields_.end() ? nullptr : &it->second;
  }

  const Field& required(std::string_view key) const {
    const Field* f = field(key);
    if (f == nullptr) site_.whole(cat("the header has no ", quote(key), " field"));
    return *f;
  }

  // "(x,y,z)" vectors or "none", as many as `count`.
  std::vector<std::optional<glm::dvec3>> vectors(const Field& f, std::size_t count) const {
    std::vector<std::optional<glm::dvec3>> out;
    std::string_view s = f.value;
    while (true) {
      s = trim(s);
      if (s.empty()) break;
      if (s.substr(0, 4) == "none") {
        out.emplace_back();
        s.remove_prefix(4);
        continue;
      }
      if (s.front() != '(')
        site_.at_line(f.line, cat("expected '(x,y,z)' or 'none' at ", quote(s)));
      const std::size_t close = s.find(')');
      if (close == std::string_view::npos) site_.at_line(f.line, "unclosed '(' in a vector");
      std::string_view inner = s.substr(1, close - 1);
      s.remove_prefix(close + 1);
      glm::dvec3 v(0.0);
      int n = 0;
      while (true) {
        const std::size_t comma = inner.find(',');
        const std::string_view part = trim(inner.substr(0, comma));
        if (n >= 3)
          site_.at_line(f.line, "a vector with more than 3 components (space dimension 3)");
        const auto d = to_double(part);
        if (!d) site_.at_line(f.line, cat("not a number: ", quote(part)));
        v[n++] = *d;
        if (comma == std::string_view::npos) break;
        inner.remove_prefix(comma + 1);
      }
      if (n != 3) site_.at_line(f.line, cat("a vector with ", n, " components (expected 3)"));
      out.emplace_back(v);
    }
    if (out.size() != count) {
      site_.at_line(f.line, cat("expected ", count, " vectors or 'none', found ", out.size()));
    }
    return out;
  }

  void interpret(VolumeFile& out) {
    // Type.
    const Field& type_field = required("type");
    const auto type = nrrd_type(type_field.value);
    if (!type) {
      site_.at_line(type_field.line,
                    cat("unknown or unsupported sample type ", quote(type_field.value)));
    }
    type_ = *type;
    out.stored_type = type_name(type_);

    // Dimension and sizes.
    const Field& dim_field = required("dimension");
    const auto dim = to_int(dim_field.value);
    if (!dim || *dim < 1)
      site_.at_line(dim_field.line, cat("bad dimension ", quote(dim_field.value)));
    dimension_ = static_cast<std::size_t>(*dim);
    const Field& sizes_field = required("sizes");
    const auto size_words = words(sizes_field.value);
    if (size_words.size() != dimension_) {
      site_.at_line(sizes_field.line, cat("dimension is ", dimension_, " but ", size_words.size(),
                                          " sizes are given"));
    }
    std::vector<std::int64_t> sizes;
    for (std::string_view w : size_words) {
      const auto v = to_int(w);
      if (!v || *v < 1)
        site_.at_line(sizes_field.line, cat("bad size ", quote(w), " (must be >= 1)"));
      sizes.push_back(*v);
    }
    if (dimension_ == 4 && sizes[0] == 1) {
      skipped_axis_ = 0;
    } else if (dimension_ == 4 && sizes[3] == 1) {
      skipped_axis_ = 3;
    } else if (dimension_ != 3) {
      site_.at_line(dim_field.line, cat("only 3-D volumes are read (dimension ", dimension_,
                                        "; 4-D only with a leading or trailing axis of size 1)"));
    }
    std::array<std::int64_t, 3> dims{};
    for (std::size_t a = 0, k = 0; a < dimension_; ++a) {
      if (a == skipped_axis_) continue;
      dims[k] = sizes[a];
      axes_[k++] = a;
    }
    out.volume.geometry.dims = dims;
    count_ = checked_count(dims, type_, site_);

    // Encoding and endian.
    const Field& enc = required("encoding");
    const std::string e = lower(enc.value);
    if (e == "raw") {
      encoding_ = Encoding::Raw;
    } else if (e == "gzip" || e == "gz") {
      encoding_ = Encoding::Gzip;
    } else if (e == "ascii" || e == "txt" || e == "text") {
      encoding_ = Encoding::Ascii;
    } else {
      site_.at_line(enc.line, cat("unsupported encoding ", quote(enc.value),
                                  " (raw, gzip and ascii are read)"));
    }
    if (encoding_ != Encoding::Ascii && sample_size(type_) > 1) {
      const Field& endian = required("endian");
      const std::string en = lower(endian.value);
      if (en == "big") {
        big_endian_ = true;
      } else if (en != "little") {
        site_.at_line(endian.line, cat("endian must be little or big, not ", quote(endian.value)));
      }
    }

    // Space.
    glm::dvec3 flip(1.0);  // file frame -> LPS
    const Field* space = field("space");
    if (space != nullptr) {
      const std::string s = lower(space->value);
      if (s == "right-anterior-superior" || s == "ras") {
        flip = {-1.0, -1.0, 1.0};
      } else if (s == "left-anterior-superior" || s == "las") {
        flip = {1.0, -1.0, 1.0};
      } else if (s == "left-posterior-superior" || s == "lps" || s == "scanner-xyz" ||
                 s == "3d-right-handed") {
      } else {
        site_.at_line(space->line, cat("unsupported space ", quote(space->value),
                                       " (RAS, LAS, LPS or scanner-xyz are read)"));
      }
    }
    if (const Field* sd = field("space dimension")) {
      if (space != nullptr) site_.at_line(sd->line, "both 'space' and 'space dimension' given");
      if (to_int(sd->value) != 3) site_.at_line(sd->line, cat("space dimension must be 3"));
    }

    glm::dmat3 steps(1.0);
    glm::dvec3 origin(0.0);
    if (const Field* dirs = field("space directions")) {
      const auto v = vectors(*dirs, dimension_);
      for (std::size_t k = 0; k < 3; ++k) {
        if (!v[axes_[k]]) {
          site_.at_line(dirs->line, cat("no space direction ('none') for axis ", axes_[k]));
        }
        steps[static_cast<int>(k)] = *v[axes_[k]] * flip;
      }
    } else if (const Field* sp = field("spacings")) {
      const auto w = words(sp->value);
      if (w.size() != dimension_) {
        site_.at_line(sp->line,
                      cat("dimension is ", dimension_, " but ", w.size(), " spacings are given"));
      }
      for (std::size_t k = 0; k < 3; ++k) {
        const auto d = to_double(w[axes_[k]]);
        if (!d) site_.at_line(sp->line, cat("not a number: ", quote(w[axes_[k]])));
        if (!(*d > 0.0) || !std::isfinite(*d)) {
          site_.at_line(sp->line, cat("spacing ", quote(w[axes_[k]]), " of axis ", axes_[k],
                                      " is not a positive finite number"));
        }
        steps[static_cast<int>(k)] = glm::dvec3(0.0);
        steps[static_cast<int>(k)][static_cast<int>(k)] = *d;
      }
    }
    if (const Field* o = field("space origin")) {
      const auto v = vectors(*o, 1);
      if (!v[0]) site_.at_line(o->line, "space origin is 'none'");
      origin = *v[0] * flip;
    }
    set_geometry_from_steps(out.volume.geometry, steps, origin, site_);
  }

  void read_samples(VolumeFile& out) {
    std::span<const std::byte> bytes = data_;
    std::size_t start = header_end_;
    std::optional<mesh_io::FileBytes> detached;
    std::string data_name = name_;
    if (const Field* df = field("data file")) {
      const auto w = words(df->value);
      if (w.size() != 1 || w[0] == "LIST") {
        site_.at_line(df->line,
                      "only a single detached data file is supported (no lists or "
                      "file name patterns)");
      }
      if (data_dir_.empty()) {
        site_.at_line(df->line, "a detached data file cannot be read from memory");
      }
      std::filesystem::path p{std::string(w[0])};
      if (p.is_relative()) p = data_dir_ / p;
      data_name = p.string();
      detached.emplace(mesh_io::read_file(p));
      bytes = detached->bytes();
      start = 0;
    } else if (!blank_line_) {
      site_.whole("the header does not end with a blank line (no data follows)");
    }
    const std::string& dname = data_name;
    const ErrorSite dsite(dname);

    // line skip, then byte skip.
    std::int64_t line_skip = 0;
    if (const Field* ls = field("line skip")) {
      const auto v = to_int(ls->value);
      if (!v || *v < 0) site_.at_line(ls->line, cat("bad line skip ", quote(ls->value)));
      line_skip = *v;
    }
    for (std::int64_t n = 0; n < line_skip; ++n) {
      const void* nl = std::memchr(bytes.data() + start, '\n', bytes.size() - start);
      if (nl == nullptr)
        dsite.at_byte(start, cat("the data ends within the ", line_skip, " skipped lines"));
      start = static_cast<std::size_t>(static_cast<const std::byte*>(nl) - bytes.data()) + 1;
    }
    std::int64_t byte_skip = 0;
    std::size_t byte_skip_line = 0;
    if (const Field* bs = field("byte skip")) {
      const auto v = to_int(bs->value);
      if (!v || *v < -1) site_.at_line(bs->line, cat("bad byte skip ", quote(bs->value)));
      byte_skip = *v;
      byte_skip_line = bs->line;
    }

    Volume& vol = out.volume;
    const auto& progress = options_.progress;
    if (encoding_ == Encoding::Raw) {
      std::size_t at = start;
      if (byte_skip == -1) {
        if (bytes.size() - start < count_.bytes) {
          dsite.whole(cat("truncated data: ", bytes.size() - start, " bytes, the header needs ",
                          count_.bytes, " (", sizes_text(vol), " ", type_name(type_), ")"));
        }
        at = bytes.size() - count_.bytes;
      } else {
        const auto skip = static_cast<std::size_t>(byte_skip);
        if (skip > bytes.size() - start) {
          dsite.whole(cat("byte skip ", skip, " is past the end of the data"));
        }
        at += skip;
      }
      if (bytes.size() - at < count_.bytes) {
        dsite.at_byte(at, cat("truncated data: ", bytes.size() - at, " bytes, the header needs ",
                              count_.bytes, " (", sizes_text(vol), " ", type_name(type_), ")"));
      }
      vol.values.resize(count_.samples);
      convert_samples(bytes.data() + at, count_.samples, type_, big_endian_, {}, vol.values.data(),
                      progress, 0, count_.bytes);
    } else if (encoding_ == Encoding::Gzip) {
      if (byte_skip == -1) {
        site_.at_line(byte_skip_line, "byte skip -1 is only allowed with raw encoding");
      }
      const auto skip = static_cast<std::size_t>(byte_skip);
      const std::span<const std::byte> packed = bytes.subspan(start);
      const std::size_t need = count_.bytes + skip;
      if (need > max_inflated_size(packed.size())) {
        dsite.at_byte(
            start,
            cat("truncated data: ", packed.size(), " compressed bytes cannot hold the ", need,
                " bytes the header needs (", sizes_text(vol), " ", type_name(type_), ")"));
      }
      Inflater inflater(packed, dsite);
      std::vector<std::byte> scratch(std::min<std::size_t>(skip, std::size_t{1} << 20));
      for (std::size_t done = 0; done < skip;) {
        const std::size_t n = std::min(scratch.size(), skip - done);
        if (inflater.read({scratch.data(), n}) != n) {
          dsite.at_byte(start, cat("truncated data: the gzip data ends within the byte skip"));
        }
        done += n;
      }
      BigVector<std::byte> raw(count_.bytes);
      const std::size_t got = inflater.read(raw);
      if (got != count_.bytes) {
        dsite.at_byte(start,
                      cat("truncated data: the gzip data holds ", got, " bytes, the header needs ",
                          count_.bytes, " (", sizes_text(vol), " ", type_name(type_), ")"));
      }
      vol.values.resize(count_.samples);
      convert_samples(raw.data(), count_.samples, type_, big_endian_, {}, vol.values.data(),
                      progress, 0, count_.bytes);
    } else {
      if (byte_skip < 0)
        site_.at_line(byte_skip_line, "byte skip -1 is only allowed with raw encoding");
      const auto skip = static_cast<std::size_t>(byte_skip);
      if (skip > bytes.size() - start)
        dsite.whole(cat("byte skip ", skip, " is past the end of the data"));
      std::size_t at = start + skip;
      // Every number takes at least one character and one separator.
      if (count_.samples > (bytes.size() - at) / 2 + 1) {
        dsite.at_byte(at,
                      cat("truncated data: ", bytes.size() - at, " bytes of text cannot hold the ",
                          count_.samples, " values of ", sizes_text(vol)));
      }
      vol.values.resize(count_.samples);
      const char* s = reinterpret_cast<const char*>(bytes.data());
      const std::size_t end = bytes.size();
      for (std::size_t n = 0; n < count_.samples; ++n) {
        while (at < end && (std::isspace(static_cast<unsigned char>(s[at])) || s[at] == ','))
          ++at;
        if (at == end) {
          dsite.at_byte(at, cat("truncated data: ", n, " values, the header needs ", count_.samples,
                                " (", sizes_text(vol), ")"));
        }
        std::size_t token_end = at;
        while (token_end < end && !std::isspace(static_cast<unsigned char>(s[token_end])) &&
               s[token_end] != ',') {
          ++token_end;
        }
        const auto v = to_double({s + at, token_end - at});
        if (!v)
          dsite.at_byte(at, cat("value ", n, ": not a number: ", quote({s + at, token_end - at})));
        vol.values[n] = static_cast<float>(*v);
        at = token_end;
        if (progress && (n & 0xfffff) == 0xfffff) progress(n * 4, count_.samples * 4);
      }
      if (progress) progress(count_.samples * 4, count_.samples * 4);
    }
    if (progress && count_.bytes == 0) progress(0, 0);
  }

  static std::string sizes_text(const Volume& v) {
    const auto& d = v.geometry.dims;
    return cat(d[0], " x ", d[1], " x ", d[2]);
  }

  std::span<const std::byte> data_;
  const std::string& name_;
  ErrorSite site_;
  const VolumeReadOptions& options_;
  const std::filesystem::path& data_dir_;
  std::map<std::string, Field, std::less<>> fields_;
  std::size_t header_end_ = 0;
  bool blank_line_ = false;
  std::string modality_;
  SampleType type_ = SampleType::UInt8;
  std::size_t dimension_ = 3;
  std::size_t skipped_axis_ = 99;
  std::array<std::size_t, 3> axes_{0, 1, 2};
  SampleCount count_;
  Encoding encoding_ = Encoding::Raw;
  bool big_endian_ = false;
};

}  // namespace

VolumeFile parse_nrrd(std::span<const std::byte> data, const std::string& name,
                      const VolumeReadOptions& options, const std::filesystem::path& data_dir) {
  return NrrdParser(data, name, options, data_dir).parse();
}

}  // namespace bisturi::volume_io

namespace bisturi {

Volume read_nrrd_from_memory(std::span<const std::byte> data, const std::string& name_for_errors,
                             const VolumeReadOptions& options,
                             const std::filesystem::path& data_dir) {
  return volume_io::parse_nrrd(data, name_for_errors, options, data_dir).volume;
}

}  // namespace bisturi
