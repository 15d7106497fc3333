#include "bisturi/devices/trace/trace_writer.h"

#include <fcntl.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <cstring>
#include <limits>
#include <thread>
#include <utility>

#include "wire.h"

namespace bisturi::devices {

namespace {

std::string system_error(const std::filesystem::path& path, const char* what) {
  return path.string() + ": " + what + ": " + std::strerror(errno);
}

/// How often the writing thread looks for sealed chunks: records never wake it.
constexpr auto kWriterPoll = std::chrono::milliseconds(2);

}  // namespace

TraceWriter::TraceWriter(const std::filesystem::path& path, TraceHeader header,
                         TraceWriterOptions options)
    : path_(path), options_(options) {
  for (std::atomic<std::int64_t>& t : last_report_in_ns_)
    t.store(-1, std::memory_order_relaxed);
  if (header.devices.size() > std::numeric_limits<std::uint16_t>::max()) {
    throw TraceError(path.string() + ": too many devices for one trace");
  }
  header.version_major = kTraceVersionMajor;
  header.version_minor = kTraceVersionMinor;
  devices_ = header.devices.size();
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) throw TraceError(system_error(path, "cannot create the trace"));
  // Every buffer the ring will use, allocated now: sealing a chunk only swaps buffers.
  for (std::size_t b = 0; b < kBuffers; ++b) {
    buffers_[b].reserve(trace_wire::kChunkHeaderSize + options_.max_chunk_bytes + 1024);
    buffers_[b].resize(trace_wire::kChunkHeaderSize);
    if (b > 0) free_[free_count_++] = b;
  }
  open_ = 0;
  std::uint64_t written = 0;
  const std::string error = write_all(trace_wire::encode_file_header(header), written);
  if (!error.empty()) {
    ::close(fd_);
    throw TraceError(error);
  }
  stats_.bytes = written;
  thread_ = std::thread([this] { write_loop(); });
}

TraceWriter::~TraceWriter() {
  try {
    close();
  } catch (const TraceError&) {
    // close() reports errors to callers that ask; a destructor has no one to tell.
  }
}

std::string TraceWriter::write_all(std::span<const std::uint8_t> bytes,
                                   std::uint64_t& written) const {
  while (!bytes.empty()) {
    const ssize_t n = ::write(fd_, bytes.data(), bytes.size());
    if (n < 0) {
      if (errno == EINTR) continue;
      return system_error(path_, "write failed");
    }
    bytes = bytes.subspan(static_cast<std::size_t>(n));
    written += static_cast<std::uint64_t>(n);
  }
  if (options_.sync_each_chunk && ::fdatasync(fd_) != 0) {
    return system_error(path_, "fdatasync failed");
  }
  return {};
}

void TraceWriter::fail_locked(std::string why) {
  if (failed_.load(std::memory_order_relaxed)) return;
  failure_ = std::move(why);
  failed_.store(true, std::memory_order_release);
  // What waits for the writing thread is dropped with the open chunk (not the one it is
  // writing: it returns that itself).
  const std::size_t keep = writing_ ? 1 : 0;
  while (sealed_count_ > keep) {
    free_[free_count_++] = sealed_[(sealed_head_ + sealed_count_ - 1) % kBuffers];
    --sealed_count_;
  }
  buffers_[open_].resize(trace_wire::kChunkHeaderSize);
  chunk_records_ = 0;
}

void TraceWriter::write_loop() {
  std::unique_lock lock(mutex_);
  for (;;) {
    if (sealed_count_ == 0) {
      if (stopping_) break;
      wake_.wait_for(lock, kWriterPoll);
      continue;
    }
    const std::size_t b = sealed_[sealed_head_];
    writing_ = true;
    const auto stall = std::exchange(injected_stall_, std::chrono::milliseconds(0));
    std::string injected = std::exchange(injected_failure_, std::string());
    lock.unlock();
    if (stall.count() > 0) std::this_thread::sleep_for(stall);
    std::uint64_t written = 0;
    const std::string error = injected.empty() ? write_all(buffers_[b], written) : injected;
    lock.lock();
    writing_ = false;
    stats_.bytes += written;
    sealed_head_ = (sealed_head_ + 1) % kBuffers;
    --sealed_count_;
    buffers_[b].resize(trace_wire::kChunkHeaderSize);
    free_[free_count_++] = b;
    if (!error.empty()) fail_locked(error);
    written_.notify_all();
  }
  written_.notify_all();
}

void TraceWriter::fail_next_write(std::string why) {
  std::lock_guard lock(mutex_);
  injected_failure_ = path_.string() + ": write failed: " + why;
}

void TraceWriter::stall_next_write(std::chrono::milliseconds stall) {
  std::lock_guard lock(mutex_);
  injected_stall_ = stall;
}

void TraceWriter::drain_locked(std::unique_lock<std::mutex>& lock) {
  wake_.notify_one();
  written_.wait(lock, [this] { return sealed_count_ == 0; });
}

void TraceWriter::seal_locked(std::uint32_t flags) {
  std::vector<std::uint8_t>& chunk = buffers_[open_];
  const std::size_t payload = chunk.size() - trace_wire::kChunkHeaderSize;
  if (free_count_ == 0) {
    fail_locked(path_.string() + ": the disk fell behind the recording (" +
                std::to_string(kBuffers - 1) + " sealed chunks waiting): recording stopped");
    return;
  }
  trace_wire::fill_chunk_header(chunk.data(), flags, stats_.chunks, chunk_records_,
                                static_cast<std::uint32_t>(payload));
  ++stats_.chunks;
  stats_.records += chunk_records_;
  sealed_[(sealed_head_ + sealed_count_) % kBuffers] = open_;
  ++sealed_count_;
  open_ = free_[--free_count_];
  chunk_records_ = 0;
}

void TraceWriter::append_locked(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                                std::span<const std::uint8_t> payload) {
  if (closed_) throw TraceError(path_.string() + ": the trace is closed");
  if (failed_.load(std::memory_order_relaxed)) return;  // recording stopped (failure() says why)
  if (type != TraceRecordType::kNote && device >= devices_) {
    throw TraceError(path_.string() + ": record for device " + std::to_string(device) +
                     ", the trace has " + std::to_string(devices_));
  }
  if (payload.size() > kTraceMaxChunkPayload / 2) {
    throw TraceError(path_.string() + ": a record of " + std::to_string(payload.size()) +
                     " bytes is too large for a trace");
  }
  // A record that would push the chunk past the format's limit goes into the next chunk.
  const std::size_t open_payload = buffers_[open_].size() - trace_wire::kChunkHeaderSize;
  if (chunk_records_ > 0 &&
      open_payload + trace_wire::kRecordHeaderSize + payload.size() > kTraceMaxChunkPayload) {
    seal_locked(0);
    if (failed_.load(std::memory_order_relaxed)) return;
  }
  std::vector<std::uint8_t>& chunk = buffers_[open_];
  if (chunk_records_ == 0) chunk_first_time_ns_ = time_ns;
  trace_wire::append_record(chunk, type, device, time_ns, payload);
  ++chunk_records_;
  ++total_records_;
  if (chunk_records_ >= options_.max_chunk_records ||
      chunk.size() - trace_wire::kChunkHeaderSize >= options_.max_chunk_bytes ||
      time_ns - chunk_first_time_ns_ >= options_.max_chunk_age_ns) {
    seal_locked(0);
  }
}

void TraceWriter::append(TraceRecordType type, std::uint16_t device, std::int64_t time_ns,
                         std::span<const std::uint8_t> payload) {
  std::unique_lock lock(mutex_);
  // A record seals at most two chunks (the one it does not fit, the one it fills).
  if (options_.wait_when_full && free_count_ < 2) {
    wake_.notify_one();
    written_.wait(lock, [this] {
      return free_count_ >= 2 || failed_.load(std::memory_order_relaxed) || closed_;
    });
  }
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
  if (device < kTimedDevices) last_report_in_ns_[device].store(time_ns, std::memory_order_relaxed);
  append(TraceRecordType::kReportIn, device, time_ns, bytes);
}

std::int64_t TraceWriter::last_report_in_ns(std::uint16_t device) const {
  return device < kTimedDevices ? last_report_in_ns_[device].load(std::memory_order_relaxed) : -1;
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
  if (!closed_ && chunk_records_ > 0 && now_ns - chunk_first_time_ns_ >= options_.max_chunk_age_ns)
    seal_locked(0);
}

void TraceWriter::flush() {
  std::unique_lock lock(mutex_);
  if (closed_) return;
  if (chunk_records_ > 0 && !failed_.load(std::memory_order_relaxed)) seal_locked(0);
  drain_locked(lock);
}

void TraceWriter::close(bool session_ended) {
  std::unique_lock lock(mutex_);
  if (closed_) return;
  if (!failed_.load(std::memory_order_relaxed)) {
    if (chunk_records_ > 0) seal_locked(0);
    drain_locked(lock);  // the end chunk below needs a free buffer
  }
  if (!failed_.load(std::memory_order_relaxed)) {
    // The end chunk: no records; its payload is the number of records before it and its flags.
    std::vector<std::uint8_t> payload;
    trace_wire::ByteWriter end(payload);
    end.u64(stats_.records);
    end.u32(session_ended ? trace_wire::kEndFlagSessionEnd : 0u);
    std::vector<std::uint8_t>& chunk = buffers_[open_];
    chunk.insert(chunk.end(), payload.begin(), payload.end());
    seal_locked(trace_wire::kChunkFlagEnd);
  }
  stopping_ = true;
  closed_ = true;
  wake_.notify_one();
  lock.unlock();
  thread_.join();
  lock.lock();
  const int fd = fd_;
  fd_ = -1;
  const bool close_failed = ::close(fd) != 0;
  if (!failure_.empty()) throw TraceError(failure_);
  if (close_failed) throw TraceError(system_error(path_, "close failed"));
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
