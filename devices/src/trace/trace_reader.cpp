#include "bisturi/devices/trace/trace_reader.h"

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <utility>

#include "wire.h"

namespace bisturi::devices {

namespace trace_detail {

/// Where the trace's bytes come from: a file or memory.
class ByteSource {
 public:
  virtual ~ByteSource() = default;
  /// Reads up to `n` bytes into `out`; fewer only at the end of the data.
  virtual std::size_t read(std::uint8_t* out, std::size_t n) = 0;
};

namespace {

class FileSource final : public ByteSource {
 public:
  explicit FileSource(std::FILE* file) : file_(file) {}
  ~FileSource() override { std::fclose(file_); }
  std::size_t read(std::uint8_t* out, std::size_t n) override {
    return std::fread(out, 1, n, file_);
  }

 private:
  std::FILE* file_;
};

class MemorySource final : public ByteSource {
 public:
  explicit MemorySource(std::span<const std::uint8_t> bytes) : bytes_(bytes) {}
  std::size_t read(std::uint8_t* out, std::size_t n) override {
    const std::size_t k = std::min(n, bytes_.size() - pos_);
    if (k > 0) std::memcpy(out, bytes_.data() + pos_, k);
    pos_ += k;
    return k;
  }

 private:
  std::span<const std::uint8_t> bytes_;
  std::size_t pos_ = 0;
};

}  // namespace

}  // namespace trace_detail

namespace {

std::string hex32(std::uint32_t v) {
  char text[16];
  std::snprintf(text, sizeof text, "0x%08x", v);
  return text;
}

TraceCorruptError truncated_error(const std::string& file, std::optional<std::uint64_t> chunk,
                                  std::uint64_t offset, const std::string& reason) {
  TraceCorruptError e(file, chunk, offset, "truncated: " + reason);
  e.set_truncated(true);
  return e;
}

bool known_type(std::uint8_t type) {
  return type >= static_cast<std::uint8_t>(TraceRecordType::kReportIn) &&
         type <= static_cast<std::uint8_t>(TraceRecordType::kNote);
}

}  // namespace

TraceReader::TraceReader(const std::filesystem::path& path) : name_(path.string()) {
  std::FILE* file = std::fopen(path.c_str(), "rb");
  if (file == nullptr) {
    throw TraceError(name_ + ": cannot open the trace: " + std::strerror(errno));
  }
  source_ = std::make_unique<trace_detail::FileSource>(file);
  read_header();
}

TraceReader::TraceReader(std::span<const std::uint8_t> bytes, std::string name)
    : source_(std::make_unique<trace_detail::MemorySource>(bytes)), name_(std::move(name)) {
  read_header();
}

TraceReader::~TraceReader() = default;

void TraceReader::read_header() {
  using namespace trace_wire;
  std::uint8_t prelude[kPreludeSize];
  const std::size_t got = source_->read(prelude, kPreludeSize);
  if (got == 0) throw truncated_error(name_, std::nullopt, 0, "the file is empty");
  const std::size_t compared = std::min(got, kMagic.size());
  if (!std::equal(prelude, prelude + compared, kMagic.begin())) {
    throw TraceError(name_ + ": not a bisturi trace (the file does not start with its magic)");
  }
  if (got < kPreludeSize) {
    throw truncated_error(name_, std::nullopt, 0,
                          "the file header needs " + std::to_string(kPreludeSize) + " bytes, " +
                              std::to_string(got) + " remain");
  }
  const auto major = static_cast<std::uint16_t>(load_le(prelude + 8, 2));
  const auto minor = static_cast<std::uint16_t>(load_le(prelude + 10, 2));
  const auto length = static_cast<std::uint32_t>(load_le(prelude + 12, 4));
  const auto stored_crc = static_cast<std::uint32_t>(load_le(prelude + 16, 4));
  if (major != kTraceVersionMajor) {
    throw TraceError(name_ + ": trace format version " + std::to_string(major) + "." +
                     std::to_string(minor) + " is not supported (this reader reads " +
                     std::to_string(kTraceVersionMajor) + ".x)");
  }
  if (length > kMaxHeaderSize) {
    throw TraceCorruptError(name_, std::nullopt, 0,
                            "header length " + std::to_string(length) + " exceeds the limit of " +
                                std::to_string(kMaxHeaderSize));
  }
  buffer_.resize(length);
  const std::size_t body = source_->read(buffer_.data(), length);
  if (body < length) {
    throw truncated_error(name_, std::nullopt, 0,
                          "the header body needs " + std::to_string(length) + " bytes, " +
                              std::to_string(body) + " remain");
  }
  std::uint32_t crc = crc32(0, std::span<const std::uint8_t>(prelude + 8, 8));
  crc = crc32(crc, buffer_);
  if (crc != stored_crc) {
    throw TraceCorruptError(
        name_, std::nullopt, 0,
        "header checksum mismatch (stored " + hex32(stored_crc) + ", computed " + hex32(crc) + ")");
  }
  try {
    header_ = decode_header_body(buffer_, major, minor);
  } catch (const WireError& e) {
    throw TraceCorruptError(name_, std::nullopt, 0, std::string("bad header: ") + e.what());
  }
  devices_ = header_.devices;
  offset_ = kPreludeSize + length;
}

void TraceReader::fail(const TraceCorruptError& error) {
  error_ = error;
  records_.clear();
  next_record_ = 0;
  throw error;
}

// Reads, checks and decodes the next chunk into records_. False at a clean end of the trace.
bool TraceReader::load_chunk() {
  using namespace trace_wire;
  records_.clear();
  next_record_ = 0;
  if (at_eof_) return false;
  const std::uint64_t index = chunk_index_;
  const std::uint64_t at = offset_;
  std::uint8_t head[kChunkHeaderSize];
  const std::size_t got = source_->read(head, kChunkHeaderSize);
  if (got == 0) {
    at_eof_ = true;
    return false;
  }
  if (ended_) fail(TraceCorruptError(name_, index, at, "data after the end-of-trace chunk"));
  if (got < kChunkHeaderSize) {
    fail(truncated_error(name_, index, at,
                         "the chunk header needs " + std::to_string(kChunkHeaderSize) + " bytes, " +
                             std::to_string(got) + " remain"));
  }
  const auto magic = static_cast<std::uint32_t>(load_le(head, 4));
  const auto flags = static_cast<std::uint32_t>(load_le(head + 4, 4));
  const std::uint64_t sequence = load_le(head + 8, 8);
  const auto record_count = static_cast<std::uint32_t>(load_le(head + 16, 4));
  const auto length = static_cast<std::uint32_t>(load_le(head + 20, 4));
  const auto stored_crc = static_cast<std::uint32_t>(load_le(head + 24, 4));
  if (magic != kChunkMagic) {
    fail(TraceCorruptError(name_, index, at, "bad chunk magic " + hex32(magic)));
  }
  if (length > kTraceMaxChunkPayload) {
    fail(TraceCorruptError(name_, index, at,
                           "payload length " + std::to_string(length) + " exceeds the limit of " +
                               std::to_string(kTraceMaxChunkPayload)));
  }
  buffer_.resize(length);
  const std::size_t body = source_->read(buffer_.data(), length);
  if (body < length) {
    fail(truncated_error(name_, index, at,
                         "the payload needs " + std::to_string(length) + " bytes, " +
                             std::to_string(body) + " remain"));
  }
  std::uint32_t crc = crc32(0, std::span<const std::uint8_t>(head, kChunkCrcCovered));
  crc = crc32(crc, buffer_);
  if (crc != stored_crc) {
    fail(TraceCorruptError(
        name_, index, at,
        "checksum mismatch (stored " + hex32(stored_crc) + ", computed " + hex32(crc) + ")"));
  }
  // Checked after the CRC: a sequence that does not follow means chunks were lost or reordered.
  if (sequence != index) {
    fail(TraceCorruptError(
        name_, index, at,
        "sequence number " + std::to_string(sequence) + ", expected " + std::to_string(index)));
  }

  if ((flags & kChunkFlagEnd) != 0) {
    if (record_count != 0 || length != kEndPayloadSize) {
      fail(TraceCorruptError(name_, index, at, "malformed end-of-trace chunk"));
    }
    const std::uint64_t total = load_le(buffer_.data(), 8);
    if (total != records_read_ + records_skipped_) {
      fail(TraceCorruptError(name_, index, at,
                             "the end-of-trace chunk counts " + std::to_string(total) +
                                 " records, the trace holds " +
                                 std::to_string(records_read_ + records_skipped_)));
    }
    ended_ = true;
    session_ended_ = (load_le(buffer_.data() + 8, 4) & kEndFlagSessionEnd) != 0;
    offset_ = at + kChunkHeaderSize + length;
    ++chunk_index_;
    return load_chunk();
  }

  // Decode every record first: the chunk is delivered whole or not at all.
  std::vector<TraceRecord> records;
  std::vector<TraceDevice> added;
  std::uint64_t skipped = 0;
  ByteCursor c(buffer_);
  for (std::uint32_t r = 0; r < record_count; ++r) {
    const std::uint64_t record_at = at + kChunkHeaderSize + c.position();
    const auto bad = [&](const std::string& why) {
      fail(TraceCorruptError(
          name_, index, at,
          "record " + std::to_string(r) + " at byte " + std::to_string(record_at) + ": " + why));
    };
    if (c.remaining() < kRecordHeaderSize) bad("the record header runs past the chunk");
    const std::uint8_t type = c.u8();
    c.u8();
    const std::uint16_t device = c.u16();
    const std::uint32_t size = c.u32();
    const std::int64_t time_ns = c.i64();
    if (size > c.remaining()) {
      bad("its payload of " + std::to_string(size) + " bytes runs past the chunk");
    }
    const auto payload = c.raw(size, "payload");
    if (!known_type(type)) {
      ++skipped;
      continue;
    }
    const auto kind = static_cast<TraceRecordType>(type);
    const std::size_t device_count = devices_.size() + added.size();
    if (kind == TraceRecordType::kDeviceAdded) {
      if (device != device_count) {
        bad("adds device " + std::to_string(device) + ", the next index is " +
            std::to_string(device_count));
      }
      try {
        added.push_back(decode_device(payload, "device " + std::to_string(device)));
      } catch (const TraceError& e) {
        bad(e.what());
      }
    } else if (kind != TraceRecordType::kNote && device >= device_count) {
      bad(std::string(to_string(kind)) + " for device " + std::to_string(device) +
          ", the trace has " + std::to_string(device_count));
    }
    if (kind == TraceRecordType::kForceCommand && size % 8 != 0) {
      bad("a force command of " + std::to_string(size) + " bytes (not whole float64 values)");
    }
    records.push_back(TraceRecord{kind, device, time_ns, {payload.begin(), payload.end()}});
  }
  if (c.remaining() != 0) {
    fail(TraceCorruptError(name_, index, at,
                           std::to_string(c.remaining()) + " bytes after the last of " +
                               std::to_string(record_count) + " records"));
  }
  devices_.insert(devices_.end(), added.begin(), added.end());
  records_ = std::move(records);
  records_skipped_ += skipped;
  offset_ = at + kChunkHeaderSize + length;
  ++chunk_index_;
  return true;
}

std::optional<TraceRecord> TraceReader::next() {
  if (error_) throw *error_;
  while (next_record_ >= records_.size()) {
    if (!load_chunk()) return std::nullopt;
  }
  ++records_read_;
  return std::move(records_[next_record_++]);
}

}  // namespace bisturi::devices
