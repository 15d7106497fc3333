#include "ply_sources.h"

#include <limits>

#include "numbers.h"

namespace bisturi::mesh_io {
namespace {

template <class T>
bool fits(std::int64_t v) {
  return v >= std::numeric_limits<T>::min() && v <= std::numeric_limits<T>::max();
}

bool fits(PlyType t, std::int64_t v) {
  switch (t) {
    case PlyType::Int8:
      return fits<std::int8_t>(v);
    case PlyType::Uint8:
      return fits<std::uint8_t>(v);
    case PlyType::Int16:
      return fits<std::int16_t>(v);
    case PlyType::Uint16:
      return fits<std::uint16_t>(v);
    case PlyType::Int32:
      return fits<std::int32_t>(v);
    case PlyType::Uint32:
      return fits<std::uint32_t>(v);
    case PlyType::Float32:
    case PlyType::Float64:
      return true;
  }
  return false;
}

}  // namespace

double PlyBinarySource::real(PlyType t) {
  const std::byte* p = take(size_of(t));
  switch (t) {
    case PlyType::Float32:
      return load<float>(p, swap_);
    case PlyType::Float64:
      return load<double>(p, swap_);
    case PlyType::Int8:
      return load<std::int8_t>(p, swap_);
    case PlyType::Uint8:
      return load<std::uint8_t>(p, swap_);
    case PlyType::Int16:
      return load<std::int16_t>(p, swap_);
    case PlyType::Uint16:
      return load<std::uint16_t>(p, swap_);
    case PlyType::Int32:
      return load<std::int32_t>(p, swap_);
    case PlyType::Uint32:
      return load<std::uint32_t>(p, swap_);
  }
  return 0.0;
}

std::int64_t PlyBinarySource::integer(PlyType t) {
  const std::byte* p = take(size_of(t));
  switch (t) {
    case PlyType::Int8:
      return load<std::int8_t>(p, swap_);
    case PlyType::Uint8:
      return load<std::uint8_t>(p, swap_);
    case PlyType::Int16:
      return load<std::int16_t>(p, swap_);
    case PlyType::Uint16:
      return load<std::uint16_t>(p, swap_);
    case PlyType::Int32:
      return load<std::int32_t>(p, swap_);
    case PlyType::Uint32:
      return load<std::uint32_t>(p, swap_);
    case PlyType::Float32:
    case PlyType::Float64:
      break;  // the header admits integer types only where integers are read
  }
  fail("an integer was expected");
}

bool PlyBinarySource::skip_fixed(const PlyElement& e) {
  std::size_t record = 0;
  for (const auto& p : e.properties) {
    if (p.is_list) return false;
    record += size_of(p.type);
  }
  begin(e, 0);
  if (record > 0 && (data_.size() - pos_) / record < e.count) fail_truncated(pos_);
  pos_ += static_cast<std::size_t>(e.count) * record;
  return true;
}

void PlyBinarySource::finish() const {
  if (pos_ != data_.size()) {
    err_.at_byte(pos_, cat(data_.size() - pos_, " bytes after the last element"));
  }
}

void PlyBinarySource::fail(std::string_view what) const {
  err_.at_byte(value_pos_, cat(element_->name, " ", record_, ": ", what));
}

void PlyBinarySource::fail_truncated(std::size_t at) const {
  err_.at_byte(at, cat(element_->name, " ", record_, ": the data ends (truncated?)"));
}

std::string_view PlyAsciiSource::take() {
  const std::string_view t = text_.token_across_lines();
  if (t.empty()) fail("the data ends (truncated?)");
  return t;
}

double PlyAsciiSource::real(PlyType t) {
  if (is_integer(t)) return static_cast<double>(integer(t));
  const std::string_view token = take();
  const auto v = parse_double(token);
  if (!v) fail(cat("bad number ", quoted(token)));
  // A float property written as text keeps the value the text gives (no rounding to float).
  return *v;
}

std::int64_t PlyAsciiSource::integer(PlyType t) {
  const std::string_view token = take();
  const auto v = parse_int(token);
  if (!v || !fits(t, *v)) fail(cat("bad ", type_name(t), " value ", quoted(token)));
  return *v;
}

void PlyAsciiSource::finish() {
  if (!text_.token_across_lines().empty()) {
    err_.at_line(text_.line_number(), "data after the last element");
  }
}

void PlyAsciiSource::fail(std::string_view what) const {
  err_.at_line(text_.line_number(), cat(element_->name, " ", record_, ": ", what));
}

}  // namespace bisturi::mesh_io
