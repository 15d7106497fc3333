#pragma once
// Reads a device trace as a stream of records, one chunk in memory at a time. Each chunk is
// checked whole (magic, sequence number, length, CRC, record framing) before any of its records is
// delivered, so a corrupt or truncated chunk stops the stream with an error that names the file,
// the chunk and its byte offset, after everything before it was delivered.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <span>
#include <string>
#include <vector>

#include "bisturi/devices/trace/trace_format.h"

namespace bisturi::devices {

namespace trace_detail {
class ByteSource;
}

class TraceReader {
 public:
  /// Opens `path` and reads its header. Throws TraceError when the file cannot be opened or is not
  /// a trace of a supported major version, TraceCorruptError when its header is bad or truncated.
  explicit TraceReader(const std::filesystem::path& path);
  /// Reads a trace held in memory (not copied: `bytes` must outlive the reader); `name` stands for
  /// the file in messages.
  TraceReader(std::span<const std::uint8_t> bytes, std::string name);
  ~TraceReader();
  TraceReader(const TraceReader&) = delete;
  TraceReader& operator=(const TraceReader&) = delete;

  const std::string& name() const { return name_; }
  const TraceHeader& header() const { return header_; }
  /// The header's devices, then those added by kDeviceAdded records of the chunks read so far.
  const std::vector<TraceDevice>& devices() const { return devices_; }

  /// The next record, or nullopt at the end of the trace. Throws TraceCorruptError at a bad or
  /// truncated chunk; every record of the chunks before it has been returned by then. After an
  /// error, every later call throws the same error. Records of types this reader does not know (a
  /// later minor version) are skipped.
  std::optional<TraceRecord> next();

  /// The chunk that the record last returned by next() came from.
  std::uint64_t current_chunk() const { return chunk_index_ == 0 ? 0 : chunk_index_ - 1; }
  /// Chunks read and checked so far (the end-of-trace chunk included).
  std::uint64_t chunks_read() const { return chunk_index_; }
  /// Records returned so far.
  std::uint64_t records_read() const { return records_read_; }
  /// Records of unknown types skipped so far.
  std::uint64_t records_skipped() const { return records_skipped_; }
  /// True once the end-of-trace chunk was read: the writer closed the trace. A trace whose writer
  /// was killed ends after its last whole chunk without it (not an error).
  bool closed_by_writer() const { return ended_; }
  /// True when the writer said the trace ends where the recorded session ended (not a cut).
  bool session_ended() const { return session_ended_; }
  /// Byte offset of the next chunk (after the last one read).
  std::uint64_t offset() const { return offset_; }

 private:
  void read_header();
  bool load_chunk();
  [[noreturn]] void fail(const TraceCorruptError& error);

  std::unique_ptr<trace_detail::ByteSource> source_;
  std::string name_;
  TraceHeader header_;
  std::vector<TraceDevice> devices_;
  std::vector<std::uint8_t> buffer_;
  std::vector<TraceRecord> records_;  // of the current chunk
  std::size_t next_record_ = 0;
  std::uint64_t chunk_index_ = 0;
  std::uint64_t offset_ = 0;
  std::uint64_t records_read_ = 0;
  std::uint64_t records_skipped_ = 0;
  bool ended_ = false;
  bool session_ended_ = false;
  bool at_eof_ = false;
  std::optional<TraceCorruptError> error_;
};

}  // namespace bisturi::devices
