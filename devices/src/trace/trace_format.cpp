#include "bisturi/devices/trace/trace_format.h"

#include <zlib.h>

#include <limits>

#include "wire.h"

namespace bisturi::devices {

namespace {

std::string describe(const std::string& file, const std::optional<std::uint64_t>& chunk,
                     std::uint64_t offset, const std::string& reason) {
  std::string where = chunk ? "chunk " + std::to_string(*chunk) : std::string("file header");
  return file + ": " + where + " at byte " + std::to_string(offset) + ": " + reason;
}

}  // namespace

const char* to_string(TraceRecordType type) {
  switch (type) {
    case TraceRecordType::kReportIn:
      return "report_in";
    case TraceRecordType::kReportOut:
      return "report_out";
    case TraceRecordType::kForceCommand:
      return "force";
    case TraceRecordType::kConnect:
      return "connect";
    case TraceRecordType::kDisconnect:
      return "disconnect";
    case TraceRecordType::kDeviceAdded:
      return "device_added";
    case TraceRecordType::kNote:
      return "note";
  }
  return "unknown";
}

std::vector<double> TraceRecord::forces_N() const {
  std::vector<double> forces;
  forces.reserve(payload.size() / 8);
  trace_wire::ByteCursor c(payload);
  while (c.remaining() >= 8)
    forces.push_back(c.f64());
  return forces;
}

TraceCorruptError::TraceCorruptError(std::string file, std::optional<std::uint64_t> chunk,
                                     std::uint64_t offset, const std::string& reason)
    : TraceError(describe(file, chunk, offset, reason)),
      file_(std::move(file)),
      chunk_(chunk),
      offset_(offset),
      reason_(reason) {}

std::vector<std::uint8_t> encode_forces(std::span<const double> forces_N) {
  std::vector<std::uint8_t> out;
  out.reserve(forces_N.size() * 8);
  trace_wire::ByteWriter w(out);
  for (const double f : forces_N)
    w.f64(f);
  return out;
}

std::vector<std::uint8_t> encode_device(const TraceDevice& device) {
  std::vector<std::uint8_t> out;
  trace_wire::ByteWriter w(out);
  w.str(device.kind);
  w.u16(device.vendor_id);
  w.u16(device.product_id);
  w.str(device.serial);
  w.str(device.product);
  w.str(device.path);
  w.str(device.driver);
  w.blob(device.report_descriptor);
  return out;
}

TraceDevice decode_device(std::span<const std::uint8_t> bytes, const std::string& what) {
  try {
    trace_wire::ByteCursor c(bytes);
    TraceDevice d;
    d.kind = c.str("kind");
    d.vendor_id = c.u16();
    d.product_id = c.u16();
    d.serial = c.str("serial");
    d.product = c.str("product");
    d.path = c.str("path");
    d.driver = c.str("driver");
    const auto descriptor = c.blob("report descriptor");
    d.report_descriptor.assign(descriptor.begin(), descriptor.end());
    // Bytes after the known fields belong to a later minor version: skipped.
    return d;
  } catch (const trace_wire::WireError& e) {
    throw TraceError(what + ": bad device description: " + e.what());
  }
}

namespace trace_wire {

std::uint32_t crc32(std::uint32_t crc, std::span<const std::uint8_t> bytes) {
  uLong c = crc;
  const std::uint8_t* p = bytes.data();
  std::size_t n = bytes.size();
  while (n > 0) {
    const uInt step = static_cast<uInt>(std::min<std::size_t>(n, std::numeric_limits<uInt>::max()));
    c = ::crc32(c, p, step);
    p += step;
    n -= step;
  }
  return static_cast<std::uint32_t>(c);
}

std::vector<std::uint8_t> encode_file_header(const TraceHeader& header) {
  std::vector<std::uint8_t> body;
  ByteWriter w(body);
  w.i64(header.start_time_ns);
  w.i64(header.wall_clock_unix_ns);
  w.str(header.producer);
  w.str(header.config);
  w.u16(static_cast<std::uint16_t>(header.devices.size()));
  for (const TraceDevice& d : header.devices)
    w.blob(encode_device(d));

  std::vector<std::uint8_t> out(kMagic.begin(), kMagic.end());
  ByteWriter p(out);
  p.u16(header.version_major);
  p.u16(header.version_minor);
  p.u32(static_cast<std::uint32_t>(body.size()));
  // The CRC covers the version, the length and the body.
  std::uint32_t crc = crc32(0, std::span(out).subspan(kMagic.size(), 8));
  crc = crc32(crc, body);
  p.u32(crc);
  p.raw(body);
  return out;
}

TraceHeader decode_header_body(std::span<const std::uint8_t> body, std::uint16_t major,
                               std::uint16_t minor) {
  ByteCursor c(body);
  TraceHeader h;
  h.version_major = major;
  h.version_minor = minor;
  h.start_time_ns = c.i64();
  h.wall_clock_unix_ns = c.i64();
  h.producer = c.str("producer");
  h.config = c.str("configuration");
  const std::uint16_t count = c.u16();
  for (std::uint16_t i = 0; i < count; ++i) {
    const auto entry = c.blob("device description");
    try {
      h.devices.push_back(decode_device(entry, "device " + std::to_string(i)));
    } catch (const TraceError& e) {
      throw WireError(e.what());
    }
  }
  return h;
}

void append_record(std::vector<std::uint8_t>& out, TraceRecordType type, std::uint16_t device,
                   std::int64_t time_ns, std::span<const std::uint8_t> payload) {
  ByteWriter w(out);
  w.u8(static_cast<std::uint8_t>(type));
  w.u8(0);
  w.u16(device);
  w.u32(static_cast<std::uint32_t>(payload.size()));
  w.i64(time_ns);
  w.raw(payload);
}

void fill_chunk_header(std::uint8_t* chunk, std::uint32_t flags, std::uint64_t sequence,
                       std::uint32_t record_count, std::uint32_t payload_length) {
  store_u32(chunk + 0, kChunkMagic);
  store_u32(chunk + 4, flags);
  store_u32(chunk + 8, static_cast<std::uint32_t>(sequence));
  store_u32(chunk + 12, static_cast<std::uint32_t>(sequence >> 32));
  store_u32(chunk + 16, record_count);
  store_u32(chunk + 20, payload_length);
  std::uint32_t crc = crc32(0, std::span(chunk, kChunkCrcCovered));
  crc = crc32(crc, std::span(chunk + kChunkHeaderSize, payload_length));
  store_u32(chunk + 24, crc);
}

void append_chunk(std::vector<std::uint8_t>& out, std::uint32_t flags, std::uint64_t sequence,
                  std::uint32_t record_count, std::span<const std::uint8_t> payload) {
  const std::size_t at = out.size();
  out.resize(at + kChunkHeaderSize);
  out.insert(out.end(), payload.begin(), payload.end());
  fill_chunk_header(out.data() + at, flags, sequence, record_count,
                    static_cast<std::uint32_t>(payload.size()));
}

}  // namespace trace_wire

}  // namespace bisturi::devices
