#pragma once
// Where the PLY body reader gets its values: binary data in either byte order, or ascii tokens.
// Both check every value against the data left and name the element record in errors.

#include <cstddef>
#include <cstdint>
#include <span>

#include "byte_order.h"
#include "parse_errors.h"
#include "ply_header.h"
#include "text_scanner.h"

namespace bisturi::mesh_io {

class PlyBinarySource {
 public:
  PlyBinarySource(std::span<const std::byte> data, std::size_t start, bool swap,
                  const ErrorSite& err)
      : data_(data), pos_(start), value_pos_(start), swap_(swap), err_(err) {}

  void begin(const PlyElement& e, std::uint64_t record) {
    element_ = &e;
    record_ = record;
    value_pos_ = pos_;
  }
  double real(PlyType t);
  std::int64_t integer(PlyType t);
  void skip(PlyType t) { take(size_of(t)); }
  void skip_items(PlyType t, std::uint64_t n) { take(items_bytes(t, n)); }
  /// Fails now, before any is read, when n items of type t are more than the data holds.
  void expect_items(PlyType t, std::uint64_t n) { (void)items_bytes(t, n); }
  /// Skips a whole element of fixed-size records at once; false when it has lists.
  bool skip_fixed(const PlyElement& e);
  void finish() const;
  std::size_t position() const { return pos_; }
  [[noreturn]] void fail(std::string_view what) const;

 private:
  const std::byte* take(std::size_t n) {
    value_pos_ = pos_;
    if (data_.size() - pos_ < n) fail_truncated(pos_);
    const std::byte* p = data_.data() + pos_;
    pos_ += n;
    return p;
  }
  std::size_t items_bytes(PlyType t, std::uint64_t n) const {
    if ((data_.size() - pos_) / size_of(t) < n) fail_truncated(pos_);
    return static_cast<std::size_t>(n) * size_of(t);
  }
  [[noreturn]] void fail_truncated(std::size_t at) const;

  std::span<const std::byte> data_;
  std::size_t pos_;
  std::size_t value_pos_;
  bool swap_;
  const ErrorSite& err_;
  const PlyElement* element_ = nullptr;
  std::uint64_t record_ = 0;
};

class PlyAsciiSource {
 public:
  PlyAsciiSource(std::string_view body, std::size_t body_offset, std::size_t first_line,
                 const ErrorSite& err)
      : text_(body, {}, first_line), body_offset_(body_offset), err_(err) {}

  void begin(const PlyElement& e, std::uint64_t record) {
    element_ = &e;
    record_ = record;
  }
  double real(PlyType t);
  std::int64_t integer(PlyType t);
  void skip(PlyType) { take(); }
  void skip_items(PlyType, std::uint64_t n) {
    for (std::uint64_t i = 0; i < n; ++i)
      take();
  }
  void expect_items(PlyType, std::uint64_t) {}
  bool skip_fixed(const PlyElement&) { return false; }
  void finish();
  std::size_t position() const { return body_offset_ + text_.line_offset(); }
  [[noreturn]] void fail(std::string_view what) const;

 private:
  std::string_view take();

  TextScanner text_;
  std::size_t body_offset_;
  const ErrorSite& err_;
  const PlyElement* element_ = nullptr;
  std::uint64_t record_ = 0;
};

}  // namespace bisturi::mesh_io
