#pragma once
// Little-endian encoding of the trace's fields, and the constants of its byte layout
// (docs/devices/trace-format.md). Internal to the trace sources.

#include <array>
#include <bit>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <span>
#include <stdexcept>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/devices/trace/trace_format.h"

namespace bisturi::devices::trace_wire {

/// 0x89 'B' 'T' 'R' 'C' CR LF SUB: a non-ASCII first byte and a CR LF pair catch text-mode
/// transfers, as PNG's signature does.
inline constexpr std::array<std::uint8_t, 8> kMagic = {0x89, 'B', 'T', 'R', 'C', 0x0D, 0x0A, 0x1A};
/// magic, u16 major, u16 minor, u32 header length, u32 header CRC.
inline constexpr std::size_t kPreludeSize = 20;
/// "CHNK" read as a little-endian u32.
inline constexpr std::uint32_t kChunkMagic = 0x4B4E4843u;
/// u32 magic, u32 flags, u64 sequence, u32 record count, u32 payload length, u32 CRC.
inline constexpr std::size_t kChunkHeaderSize = 28;
/// Bytes of the chunk header that the CRC covers (everything before the CRC field).
inline constexpr std::size_t kChunkCrcCovered = 24;
inline constexpr std::uint32_t kChunkFlagEnd = 1u;
/// The end-of-trace chunk's payload: u64 records before it, u32 flags.
inline constexpr std::uint32_t kEndPayloadSize = 12;
/// End flag: the trace ends where the recorded session ended (a cut leaves it clear).
inline constexpr std::uint32_t kEndFlagSessionEnd = 1u;
/// u8 type, u8 reserved, u16 device, u32 payload length, i64 time.
inline constexpr std::size_t kRecordHeaderSize = 16;
/// The header must fit in this many bytes (descriptors and configuration are small).
inline constexpr std::uint32_t kMaxHeaderSize = 16u << 20;

/// CRC-32 (ISO-HDLC polynomial, zlib's crc32) of `bytes`, continuing from `crc`.
std::uint32_t crc32(std::uint32_t crc, std::span<const std::uint8_t> bytes);

/// Appends little-endian fields to a byte vector.
class ByteWriter {
 public:
  explicit ByteWriter(std::vector<std::uint8_t>& out) : out_(out) {}

  void u8(std::uint8_t v) { out_.push_back(v); }
  void u16(std::uint16_t v) { put(v, 2); }
  void u32(std::uint32_t v) { put(v, 4); }
  void u64(std::uint64_t v) { put(v, 8); }
  void i64(std::int64_t v) { put(static_cast<std::uint64_t>(v), 8); }
  void f64(double v) { put(std::bit_cast<std::uint64_t>(v), 8); }
  void raw(std::span<const std::uint8_t> bytes) {
    out_.insert(out_.end(), bytes.begin(), bytes.end());
  }
  /// u32 length, then the bytes.
  void blob(std::span<const std::uint8_t> bytes) {
    u32(static_cast<std::uint32_t>(bytes.size()));
    raw(bytes);
  }
  void str(std::string_view s) {
    blob(std::span(reinterpret_cast<const std::uint8_t*>(s.data()), s.size()));
  }

 private:
  void put(std::uint64_t v, int n) {
    for (int i = 0; i < n; ++i)
      out_.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
  }
  std::vector<std::uint8_t>& out_;
};

/// Writes a little-endian u32 at `p`.
inline void store_u32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i)
    p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}
inline std::uint64_t load_le(const std::uint8_t* p, int n) {
  std::uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i)
    v = (v << 8) | p[i];
  return v;
}

/// Thrown by ByteCursor when a field runs past the end; the reader turns it into a TraceError
/// that names the file, the chunk and the byte.
struct WireError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

/// Reads little-endian fields from a span, checking every length.
class ByteCursor {
 public:
  explicit ByteCursor(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}

  std::size_t position() const { return pos_; }
  std::size_t remaining() const { return bytes_.size() - pos_; }

  std::uint8_t u8() { return static_cast<std::uint8_t>(get(1, "u8")); }
  std::uint16_t u16() { return static_cast<std::uint16_t>(get(2, "u16")); }
  std::uint32_t u32() { return static_cast<std::uint32_t>(get(4, "u32")); }
  std::uint64_t u64() { return get(8, "u64"); }
  std::int64_t i64() { return static_cast<std::int64_t>(get(8, "i64")); }
  double f64() { return std::bit_cast<double>(get(8, "f64")); }
  std::span<const std::uint8_t> raw(std::size_t n, const char* what) {
    need(n, what);
    const auto s = bytes_.subspan(pos_, n);
    pos_ += n;
    return s;
  }
  std::span<const std::uint8_t> blob(const char* what) { return raw(u32(), what); }
  std::string str(const char* what) {
    const auto s = blob(what);
    return std::string(reinterpret_cast<const char*>(s.data()), s.size());
  }

 private:
  void need(std::size_t n, const char* what) const {
    if (n > remaining()) {
      throw WireError(std::string(what) + " needs " + std::to_string(n) + " bytes, " +
                      std::to_string(remaining()) + " left");
    }
  }
  std::uint64_t get(int n, const char* what) {
    need(static_cast<std::size_t>(n), what);
    const std::uint64_t v = load_le(bytes_.data() + pos_, n);
    pos_ += static_cast<std::size_t>(n);
    return v;
  }
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
};

/// The whole file header (prelude and body) of `header`.
std::vector<std::uint8_t> encode_file_header(const TraceHeader& header);
/// Decodes a header body (the bytes after the prelude); throws WireError.
TraceHeader decode_header_body(std::span<const std::uint8_t> body, std::uint16_t major,
                               std::uint16_t minor);
/// Appends one record (header and payload) to `out`.
void append_record(std::vector<std::uint8_t>& out, TraceRecordType type, std::uint16_t device,
                   std::int64_t time_ns, std::span<const std::uint8_t> payload);
/// Fills the chunk header at `chunk[0, kChunkHeaderSize)`, whose payload of `payload_length` bytes
/// follows it in memory, and its CRC.
void fill_chunk_header(std::uint8_t* chunk, std::uint32_t flags, std::uint64_t sequence,
                       std::uint32_t record_count, std::uint32_t payload_length);
/// Encodes a whole chunk (header with CRC, then payload).
void append_chunk(std::vector<std::uint8_t>& out, std::uint32_t flags, std::uint64_t sequence,
                  std::uint32_t record_count, std::span<const std::uint8_t> payload);

}  // namespace bisturi::devices::trace_wire
