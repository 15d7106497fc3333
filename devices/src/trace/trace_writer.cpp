#include "bisturi/devices/trace/trace_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <limits>

#include "wire.h"

namespace bisturi::devices {

namespace {

std::string system_error(const std::filesystem::path& path, const char* what) {
  return path.string() + ": " + what + ": " + std::strerror(errno);
}

}  // namespace

TraceWriter::TraceWriter(const std::filesystem::path& path, TraceHeader header,
                         TraceWriterOptions options)
    : path_(path), options_(options) {
  if (header.devices.size() > std::numeric_limits<std::uint16_t>::max()) {
    throw TraceError(path.string() + ": too many devices for one trace");
  }
  header.version_major = kTraceVersionMajor;
  header.version_minor = kTraceVersionMinor;
  devices_ = header.devices.size();
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw TraceError(system_error(path, "cannot create the trace"));
  chunk_.reserve(trace_wire::kChunkHeaderSize + options_.max_chunk_bytes + 1024);
  chunk_.resize(trace_wire::kChunkHeaderSize);
  const std::vector<std::uint8_t> bytes = trace_wire::encode_file_header(header);
  std::lock_guard lock(mutex_);
  try {
    write_all_locked(bytes);
  } catch (...) {
    ::close(fd_);
    throw;
  }
}

TraceWriter::~TraceWriter() {
  try {
    close();
  } catch (const TraceError&) {
    // close() reports errors to callers that ask; a destructor has no one to tell.
  }
  std::lock_guard lock(mutex_);
  if (fd_ >= 0) ::close(fd_);
}

void TraceWriter::write_all_locked(std::span<const std::uint8_t> bytes) {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      const std::string message = system_error(path_, "write failed");
      ::close(fd_);
      fd_ = -1;
      failure_ = message;
      throw TraceError(message);
    }
    bytes = bytes.subspan(static_cast<std::size_t>(n));
    stats_.bytes += static_cast<std::uint64_t>(n);
  }
  if (options_.sync_each_chunk && ::fdatasync(fd_) != 0) {
    const std::string message = system_error(path_, "fdatasync failed");
    ::close(fd_);
    fd_ = -1;
    failure_ = message;
    throw TraceError(message);
  }
}

void TraceWriter::seal_locked(std::uint32_t flags) {
  const std::size_t payload = chunk_.size() - trace_wire::kChunkHeaderSize;
  trace_wire::fill_chunk_header(chunk_.data(), flags, stats_.chunks, chunk_records_,
                                static_cast<std::uint32_t>(payload));
  write_all_locked(chunk_);
  ++stats_.chunks;
  stats_.records += chunk_records_;
  chunk_.resize(trace_wire::kChunkHeaderSize);
  chunk_records_ = 0;
}

void TraceWriter::append_locked(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                                std::span<const std::uint8_t> payload) {
  if (!failure_.empty()) return;  // recording stopped at the failed write (failure() says why)
  if (fd_ < 0) throw TraceError(path_.string() + ": the trace is closed");
  if (type != TraceRecordType::kNote && device >= devices_) {
    throw TraceError(path_.string() + ": record for device " + std::to_string(device) +
                     ", the trace has " + std::to_string(devices_));
  }
  if (payload.size() > kTraceMaxChunkPayload / 2) {
    throw TraceError(path_.string() + ": a record of " + std::to_string(payload.size()) +
                     " bytes is too large for a trace");
  }
  // A record that would push the chunk past the format's limit goes into the next chunk.
  const std::size_t open_payload = chunk_.size() - trace_wire::kChunkHeaderSize;
  if (chunk_records_ > 0 &&
      open_payload + trace_wire::kRecordHeaderSize + payload.size() > kTraceMaxChunkPayload) {
    seal_locked(0);
  }
  if (chunk_records_ == 0) chunk_first_time_ns_ = time_ns;
  trace_wire::append_record(chunk_, type, device, time_ns, payload);
  ++chunk_records_;
  ++total_records_;
  if (chunk_records_ >= options_.max_chunk_records ||
      chunk_.size() - trace_wire::kChunkHeaderSize >= options_.max_chunk_bytes ||
      time_ns - chunk_first_time_ns_ >= options_.max_chunk_age_ns) {
    seal_locked(0);
  }
}

void TraceWriter::append(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                         std::span<const std::uint8_t> payload) {
  std::lock_guard lock(mutex_);
  append_locked(type, device, time_ns, payload);
}

std::uint16_t TraceWriter::add_device(std::int64_t time_ns, const TraceDevice& device) {
  std::lock_guard lock(mutex_);
  if (devices_ >= std::numeric_limits<std::uint16_t>::max()) {
    throw TraceError(path_.string() + ": too many devices for one trace");
  }
  const auto index = static_cast<std::uint16_t>(devices_);
  ++devices_;
  try {
    append_locked(TraceRecordType::kDeviceAdded, index, time_ns, encode_device(device));
  } catch (...) {
    --devices_;
    throw;
  }
  return index;
}

void TraceWriter::report_in(std::uint16_t device, std::int64_t time_ns,
                            std::span<const std::uint8_t> bytes) {
  append(TraceRecordType::kReportIn, device, time_ns, bytes);
}

void TraceWriter::report_out(std::uint16_t device, std::int64_t time_ns,
                             std::span<const std::uint8_t> bytes) {
  append(TraceRecordType::kReportOut, device, time_ns, bytes);
}

void TraceWriter::force_command(std::uint16_t device, std::int64_t time_ns,
                                std::span<const double> force_N) {
  // Eight actuators cover a glove; more take the allocating path.
  std::uint8_t small[64];
  if (force_N.size() * 8 <= sizeof small) {
    std::size_t n = 0;
    for (const double f : force_N) {
      std::uint64_t bits = 0;
      std::memcpy(&bits, &f, sizeof bits);
      for (int i = 0; i < 8; ++i)
        small[n++] = static_cast<std::uint8_t>(bits >> (8 * i));
    }
    append(TraceRecordType::kForceCommand, device, time_ns, std::span(small, n));
    return;
  }
  append(TraceRecordType::kForceCommand, device, time_ns, encode_forces(force_N));
}

void TraceWriter::connect(std::uint16_t device, std::int64_t time_ns) {
  append(TraceRecordType::kConnect, device, time_ns, {});
}

void TraceWriter::disconnect(std::uint16_t device, std::int64_t time_ns) {
  append(TraceRecordType::kDisconnect, device, time_ns, {});
}

void TraceWriter::note(std::int64_t time_ns, std::string_view text) {
  append(TraceRecordType::kNote, 0, time_ns,
         std::span(reinterpret_cast<const std::uint8_t*>(text.data()), text.size()));
}

void TraceWriter::poll(std::int64_t now_ns) {
  std::lock_guard lock(mutex_);
  if (fd_ >= 0 && chunk_records_ > 0 &&
      now_ns - chunk_first_time_ns_ >= options_.max_chunk_age_ns) {
    seal_locked(0);
  }
}

void TraceWriter::flush() {
  std::lock_guard lock(mutex_);
  if (fd_ >= 0 && chunk_records_ > 0) seal_locked(0);
}

void TraceWriter::close(bool session_ended) {
  std::lock_guard lock(mutex_);
  if (fd_ < 0) return;
  if (chunk_records_ > 0) seal_locked(0);
  // The end chunk: no records; its payload is the number of records before it and its flags.
  std::vector<std::uint8_t> payload;
  trace_wire::ByteWriter end(payload);
  end.u64(stats_.records);
  end.u32(session_ended ? trace_wire::kEndFlagSessionEnd : 0u);
  chunk_.insert(chunk_.end(), payload.begin(), payload.end());
  seal_locked(trace_wire::kChunkFlagEnd);
  const int fd = fd_;
  fd_ = -1;
  if (::close(fd) != 0) throw TraceError(system_error(path_, "close failed"));
}

std::size_t TraceWriter::device_count() const {
  std::lock_guard lock(mutex_);
  return devices_;
}

std::string TraceWriter::failure() const {
  std::lock_guard lock(mutex_);
  return failure_;
}

TraceWriterStats TraceWriter::stats() const {
  std::lock_guard lock(mutex_);
  return stats_;
}

}  // namespace bisturi::devices
