// libFuzzer: the device trace reader (header, chunk framing, checksums, records) and the summary
// `bisturi trace inspect` builds from it. Byte 0 picks the mode: odd = the checksums of the header
// and of every chunk are recomputed first, so that mutations reach the record decoder instead of
// stopping at a checksum; even = the bytes are read as they are. The rest is the trace.
// A TraceError that names the input is the only allowed failure, and what is delivered must hold
// together (device indices, force payloads, chunk counts).
#include <zlib.h>

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/trace/trace_tools.h"

namespace {

[[noreturn]] void broken(const char* what) {
  std::fprintf(stderr, "trace reader invariant broken: %s\n", what);
  std::abort();
}

std::uint32_t le32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | static_cast<std::uint32_t>(p[1]) << 8 |
         static_cast<std::uint32_t>(p[2]) << 16 | static_cast<std::uint32_t>(p[3]) << 24;
}

void put32(std::uint8_t* p, std::uint32_t v) {
  for (int i = 0; i < 4; ++i)
    p[i] = static_cast<std::uint8_t>(v >> (8 * i));
}

std::uint32_t crc(std::uint32_t c, const std::uint8_t* p, std::size_t n) {
  return static_cast<std::uint32_t>(crc32(c, p, static_cast<uInt>(n)));
}

// Recomputes the header CRC and each chunk CRC where the framing allows
// (docs/devices/trace-format.md).
void fix_checksums(std::vector<std::uint8_t>& b) {
  if (b.size() < 20) return;
  const std::size_t header = le32(b.data() + 12);
  if (header > b.size() - 20) return;
  put32(b.data() + 16, crc(crc(0, b.data() + 8, 8), b.data() + 20, header));
  std::size_t at = 20 + header;
  while (b.size() - at >= 28) {
    const std::size_t payload = le32(b.data() + at + 20);
    if (payload > b.size() - at - 28) return;
    put32(b.data() + at + 24, crc(crc(0, b.data() + at, 24), b.data() + at + 28, payload));
    at += 28 + payload;
  }
}

void read_all(std::span<const std::uint8_t> bytes, const std::string& name) {
  namespace bd = bisturi::devices;
  try {
    bd::TraceReader reader(bytes, name);
    std::uint64_t records = 0;
    try {
      while (auto r = reader.next()) {
        ++records;
        if (r->type != bd::TraceRecordType::kNote && r->device >= reader.devices().size()) {
          broken("a record for a device the trace does not have");
        }
        if (r->type == bd::TraceRecordType::kForceCommand &&
            r->forces_N().size() * 8 != r->payload.size()) {
          broken("a force payload that is not whole float64 values");
        }
      }
    } catch (const bd::TraceCorruptError& e) {
      if (!e.chunk()) broken("a chunk error without its chunk");
      if (e.offset() > bytes.size()) broken("an offset past the end");
    }
    if (reader.records_read() != records) broken("records_read");
    if (reader.offset() > bytes.size()) broken("offset past the end");
    bd::TraceReader again(bytes, name);
    const bd::TraceSummary s = bd::summarize_trace(again);
    if (s.records != records) broken("the summary counts other records");
    if (s.good_bytes != reader.offset()) broken("the summary's good bytes");
    if (s.devices.size() != again.devices().size()) broken("the summary's devices");
  } catch (const bd::TraceError& e) {
    if (std::string(e.what()).rfind(name + ": ", 0) != 0)
      broken("the message does not name the file");
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  std::vector<std::uint8_t> bytes(data + 1, data + size);
  if ((data[0] & 1) != 0) fix_checksums(bytes);
  read_all(bytes, "fuzz-input");
  return 0;
}
