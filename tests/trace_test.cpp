// Device traces: the file format (round trips, checksums, truncation at every byte, a killed
// writer), recording and replay of the simulated glove (a match, and a flipped output byte found),
// and the cut.

#include <fcntl.h>
#include <gtest/gtest.h>
#include <signal.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/trace/trace_replay.h"
#include "bisturi/devices/trace/trace_tools.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "trace_fixture.h"

namespace bisturi::devices {
namespace {

namespace fs = std::filesystem;
using Bytes8 = std::vector<std::uint8_t>;

class TraceTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path() /
           ("bisturi_trace_test_" + std::to_string(::getpid()) + "_" + info->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path file(const std::string& name) const { return dir_ / name; }

  fs::path dir_;
};

Bytes8 read_bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return Bytes8(std::istreambuf_iterator<char>(in), {});
}

void write_bytes(const fs::path& path, const Bytes8& bytes) {
  std::ofstream out(path, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()),
            static_cast<std::streamsize>(bytes.size()));
}

std::uint64_t le(const Bytes8& b, std::size_t at, int n) {
  std::uint64_t v = 0;
  for (int i = n - 1; i >= 0; --i)
    v = (v << 8) | b[at + static_cast<std::size_t>(i)];
  return v;
}

// The chunk layout of a trace, parsed here independently of TraceReader.
struct ChunkInfo {
  std::size_t offset = 0;
  std::size_t end = 0;
  std::uint32_t records = 0;
};
struct Layout {
  std::size_t header_end = 0;
  std::vector<ChunkInfo> chunks;
};

Layout layout_of(const Bytes8& b) {
  Layout l;
  l.header_end = 20 + le(b, 12, 4);
  std::size_t at = l.header_end;
  while (at < b.size()) {
    ChunkInfo c;
    c.offset = at;
    c.records = static_cast<std::uint32_t>(le(b, at + 16, 4));
    c.end = at + 28 + le(b, at + 20, 4);
    l.chunks.push_back(c);
    at = c.end;
  }
  return l;
}

struct ReadAll {
  std::vector<TraceRecord> records;
  std::optional<TraceCorruptError> error;
  bool closed = false;
};

ReadAll read_all(TraceReader& reader) {
  ReadAll r;
  try {
    while (auto rec = reader.next())
      r.records.push_back(std::move(*rec));
  } catch (const TraceCorruptError& e) {
    r.error = e;
  }
  r.closed = reader.closed_by_writer();
  return r;
}

TraceDevice glove_device() {
  TraceDevice d;
  d.kind = "hid";
  d.vendor_id = 0x1209;
  d.product_id = 0xB157;
  d.serial = "G-1";
  d.product = "Test glove";
  d.path = "virtual:glove";
  d.driver = "hid-glove";
  d.report_descriptor = {0x05, 0x03, 0x09, 0x04, 0xA1, 0x01, 0xC0};
  return d;
}

// A trace with every record type, written in chunks of `per_chunk` records.
std::vector<TraceRecord> write_sample(const fs::path& path, std::size_t per_chunk,
                                      std::size_t reports = 40) {
  TraceHeader header;
  header.start_time_ns = 1'000'000;
  header.wall_clock_unix_ns = 1'700'000'000'000'000'000;
  header.producer = "trace_test";
  header.config = R"({"scene":"liver","force_guard":{"ramp_in_ns":40000000}})";
  header.devices = {glove_device()};
  TraceWriterOptions options;
  options.max_chunk_records = per_chunk;
  TraceWriter writer(path, header, options);
  std::vector<TraceRecord> expected;
  const auto add = [&](TraceRecordType type, std::uint16_t device, std::int64_t t, Bytes8 p) {
    expected.push_back(TraceRecord{type, device, t, std::move(p)});
  };
  writer.connect(0, 1'000'000);
  add(TraceRecordType::kConnect, 0, 1'000'000, {});
  TraceDevice tracker = glove_device();
  tracker.product = "Tracker";
  tracker.driver = "hid-tracker";
  tracker.report_descriptor.clear();
  EXPECT_EQ(writer.add_device(1'000'100, tracker), 1);
  add(TraceRecordType::kDeviceAdded, 1, 1'000'100, encode_device(tracker));
  for (std::size_t i = 0; i < reports; ++i) {
    const std::int64_t t = 2'000'000 + static_cast<std::int64_t>(i) * 1'000'000;
    Bytes8 in(1 + i % 17);
    for (std::size_t k = 0; k < in.size(); ++k)
      in[k] = static_cast<std::uint8_t>(i * 31 + k);
    writer.report_in(static_cast<std::uint16_t>(i % 2), t, in);
    add(TraceRecordType::kReportIn, static_cast<std::uint16_t>(i % 2), t, in);
    const std::vector<double> force = {0.5 * static_cast<double>(i), -1.25, 3e-9,
                                       std::numeric_limits<double>::quiet_NaN()};
    writer.force_command(0, t + 10, force);
    add(TraceRecordType::kForceCommand, 0, t + 10, encode_forces(force));
    const Bytes8 out = {0x02, static_cast<std::uint8_t>(i), 0xFF};
    writer.report_out(0, t + 20, out);
    add(TraceRecordType::kReportOut, 0, t + 20, out);
    if (i == reports / 2) {
      writer.disconnect(0, t + 30);
      add(TraceRecordType::kDisconnect, 0, t + 30, {});
      writer.note(t + 40, "glove unplugged");
      add(TraceRecordType::kNote, 0, t + 40,
          {'g', 'l', 'o', 'v', 'e', ' ', 'u', 'n', 'p', 'l', 'u', 'g', 'g', 'e', 'd'});
      writer.connect(0, t + 50);
      add(TraceRecordType::kConnect, 0, t + 50, {});
    }
  }
  writer.close();
  return expected;
}

// Records delivered by whole chunks that end at or before `limit`.
std::size_t records_before(const Layout& l, std::size_t limit) {
  std::size_t n = 0;
  for (const ChunkInfo& c : l.chunks) {
    if (c.end <= limit) n += c.records;
  }
  return n;
}

TEST_F(TraceTest, RoundTripKeepsHeaderAndEveryRecord) {
  const fs::path path = file("round.btrace");
  const std::vector<TraceRecord> expected = write_sample(path, 7);
  TraceReader reader(path);
  EXPECT_EQ(reader.header().producer, "trace_test");
  EXPECT_EQ(reader.header().start_time_ns, 1'000'000);
  EXPECT_EQ(reader.header().wall_clock_unix_ns, 1'700'000'000'000'000'000);
  EXPECT_EQ(reader.header().config, R"({"scene":"liver","force_guard":{"ramp_in_ns":40000000}})");
  EXPECT_EQ(reader.header().version_major, kTraceVersionMajor);
  ASSERT_EQ(reader.header().devices.size(), 1u);
  EXPECT_EQ(reader.header().devices[0], glove_device());
  const ReadAll all = read_all(reader);
  EXPECT_FALSE(all.error);
  EXPECT_TRUE(all.closed);
  EXPECT_TRUE(reader.session_ended());
  ASSERT_EQ(all.records.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    EXPECT_EQ(all.records[i].type, expected[i].type) << i;
    EXPECT_EQ(all.records[i].device, expected[i].device) << i;
    EXPECT_EQ(all.records[i].time_ns, expected[i].time_ns) << i;
    EXPECT_EQ(all.records[i].payload, expected[i].payload) << i;
  }
  ASSERT_EQ(reader.devices().size(), 2u);
  EXPECT_EQ(reader.devices()[1].driver, "hid-tracker");
  const std::vector<double> f = all.records[3].forces_N();
  ASSERT_EQ(f.size(), 4u);
  EXPECT_EQ(f[0], 0.0);
  EXPECT_EQ(f[1], -1.25);
  EXPECT_EQ(f[2], 3e-9);
  EXPECT_TRUE(std::isnan(f[3]));
  // 7 records per chunk, and the end-of-trace chunk.
  EXPECT_EQ(reader.chunks_read(), (expected.size() + 6) / 7 + 1);
  EXPECT_EQ(reader.offset(), fs::file_size(path));
}

TEST_F(TraceTest, MemoryReaderMatchesFileReader) {
  const fs::path path = file("memory.btrace");
  const std::vector<TraceRecord> expected = write_sample(path, 5);
  const Bytes8 bytes = read_bytes(path);
  TraceReader reader(bytes, "in-memory");
  const ReadAll all = read_all(reader);
  EXPECT_FALSE(all.error);
  EXPECT_EQ(all.records, expected);
}

TEST_F(TraceTest, EmptyTraceIsValid) {
  const fs::path path = file("empty.btrace");
  TraceHeader header;
  header.producer = "empty";
  { TraceWriter writer(path, header); }
  TraceReader reader(path);
  const ReadAll all = read_all(reader);
  EXPECT_TRUE(all.records.empty());
  EXPECT_FALSE(all.error);
  EXPECT_TRUE(all.closed);
  const TraceSummary s = [&] {
    TraceReader again(path);
    return summarize_trace(again);
  }();
  EXPECT_EQ(s.records, 0u);
  EXPECT_EQ(s.chunks, 1u);
  EXPECT_EQ(s.duration_s(), 0.0);
}

TEST_F(TraceTest, WriterRejectsUnknownDevicesAndWritesAfterClose) {
  TraceHeader header;
  header.devices = {glove_device()};
  TraceWriter writer(file("reject.btrace"), header);
  const Bytes8 r = {1, 2, 3};
  EXPECT_THROW(writer.report_in(1, 0, r), TraceError);
  writer.report_in(0, 0, r);
  writer.close();
  EXPECT_THROW(writer.report_in(0, 1, r), TraceError);
  EXPECT_THROW(TraceWriter(dir_ / "missing" / "x.btrace", header), TraceError);
}

// Every single flipped byte is caught by a checksum: the error names the chunk (or the header)
// and its offset, and every chunk before it is delivered.
TEST_F(TraceTest, EveryFlippedByteIsDetectedAtItsChunk) {
  const fs::path path = file("flip.btrace");
  write_sample(path, 6, 12);
  const Bytes8 good = read_bytes(path);
  const Layout l = layout_of(good);
  ASSERT_GE(l.chunks.size(), 4u);
  for (std::size_t at = 0; at < good.size(); ++at) {
    Bytes8 bad = good;
    bad[at] ^= 0x5A;
    std::optional<TraceReader> reader;
    try {
      reader.emplace(bad, "flipped.btrace");
    } catch (const TraceError& e) {
      EXPECT_LT(at, l.header_end) << "byte " << at << ": " << e.what();
      EXPECT_EQ(std::string(e.what()).rfind("flipped.btrace: ", 0), 0u) << e.what();
      continue;
    }
    ASSERT_GE(at, l.header_end) << "a flipped header byte " << at << " went unnoticed";
    const ReadAll all = read_all(*reader);
    ASSERT_TRUE(all.error) << "a flipped byte " << at << " went unnoticed";
    std::size_t chunk = 0;
    while (l.chunks[chunk].end <= at)
      ++chunk;
    EXPECT_EQ(all.error->chunk(), chunk) << "byte " << at << ": " << all.error->what();
    EXPECT_EQ(all.error->offset(), l.chunks[chunk].offset);
    EXPECT_EQ(all.records.size(), records_before(l, l.chunks[chunk].offset)) << "byte " << at;
    const std::string expected_start = "flipped.btrace: chunk " + std::to_string(chunk) +
                                       " at byte " + std::to_string(l.chunks[chunk].offset) + ": ";
    EXPECT_EQ(std::string(all.error->what()).rfind(expected_start, 0), 0u) << all.error->what();
  }
}

// A trace cut at any byte never crashes the reader: it delivers the whole chunks before the cut
// and reports the chunk the cut falls in (none when the cut falls between chunks).
TEST_F(TraceTest, TruncationAtEveryByteKeepsTheGoodPrefix) {
  const fs::path path = file("cut.btrace");
  write_sample(path, 5, 10);
  const Bytes8 good = read_bytes(path);
  const Layout l = layout_of(good);
  for (std::size_t size = 0; size <= good.size(); ++size) {
    const Bytes8 part(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(size));
    std::optional<TraceReader> reader;
    try {
      reader.emplace(part, "part.btrace");
    } catch (const TraceCorruptError& e) {
      EXPECT_LT(size, l.header_end);
      EXPECT_TRUE(e.truncated());
      EXPECT_FALSE(e.chunk());
      EXPECT_NE(std::string(e.what()).find("part.btrace: file header at byte 0: truncated"),
                std::string::npos)
          << e.what();
      continue;
    }
    ASSERT_GE(size, l.header_end) << size;
    const ReadAll all = read_all(*reader);
    EXPECT_EQ(all.records.size(), records_before(l, size)) << "cut at " << size;
    bool boundary = size == l.header_end;
    for (const ChunkInfo& c : l.chunks)
      boundary = boundary || c.end == size;
    if (boundary) {
      EXPECT_FALSE(all.error) << "cut at " << size << ": " << all.error->what();
      EXPECT_EQ(all.closed, size == good.size());
    } else {
      ASSERT_TRUE(all.error) << "cut at " << size;
      EXPECT_TRUE(all.error->truncated()) << all.error->what();
      std::size_t chunk = 0;
      while (l.chunks[chunk].end < size)
        ++chunk;
      EXPECT_EQ(all.error->chunk(), chunk);
      EXPECT_EQ(all.error->offset(), l.chunks[chunk].offset);
      EXPECT_FALSE(all.closed);
    }
  }
}

TEST_F(TraceTest, ReorderedOrRepeatedChunksAreCaught) {
  const fs::path path = file("seq.btrace");
  write_sample(path, 4, 8);
  const Bytes8 good = read_bytes(path);
  const Layout l = layout_of(good);
  // Chunk 1 again in place of chunk 2.
  Bytes8 bad(good.begin(), good.begin() + static_cast<std::ptrdiff_t>(l.chunks[2].offset));
  bad.insert(bad.end(), good.begin() + static_cast<std::ptrdiff_t>(l.chunks[1].offset),
             good.begin() + static_cast<std::ptrdiff_t>(l.chunks[1].end));
  TraceReader reader(bad, "seq.btrace");
  const ReadAll all = read_all(reader);
  ASSERT_TRUE(all.error);
  EXPECT_EQ(all.error->chunk(), 2u);
  EXPECT_NE(std::string(all.error->what()).find("sequence number 1, expected 2"), std::string::npos)
      << all.error->what();
  EXPECT_EQ(all.records.size(), l.chunks[0].records + l.chunks[1].records);
  // Bytes after the end-of-trace chunk.
  Bytes8 trailing = good;
  trailing.insert(trailing.end(), good.begin() + static_cast<std::ptrdiff_t>(l.chunks[0].offset),
                  good.begin() + static_cast<std::ptrdiff_t>(l.chunks[0].end));
  TraceReader tail(trailing, "tail.btrace");
  const ReadAll t = read_all(tail);
  ASSERT_TRUE(t.error);
  EXPECT_NE(std::string(t.error->what()).find("after the end-of-trace chunk"), std::string::npos);
  // The error repeats on later calls.
  EXPECT_THROW(tail.next(), TraceCorruptError);
}

TEST_F(TraceTest, ForeignFilesAndOtherVersionsAreRefused) {
  const fs::path path = file("v.btrace");
  write_sample(path, 8, 2);
  Bytes8 bytes = read_bytes(path);
  Bytes8 text = {'s', 'o', 'l', 'i', 'd', ' ', 'x', '\n'};
  try {
    TraceReader reader(text, "model.stl");
    FAIL() << "a text file was read as a trace";
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("model.stl: not a bisturi trace"), std::string::npos);
  }
  bytes[8] = 2;  // major version 2
  try {
    TraceReader reader(bytes, "v2.btrace");
    FAIL() << "a version 2 trace was read";
  } catch (const TraceCorruptError&) {
    FAIL() << "a newer version is not corruption";
  } catch (const TraceError& e) {
    EXPECT_NE(std::string(e.what()).find("version 2.0 is not supported"), std::string::npos)
        << e.what();
  }
  EXPECT_THROW(TraceReader(file("absent.btrace")), TraceError);
}

// A process killed while recording leaves every chunk it had sealed (and the writing thread had
// time to take: it looks every couple of milliseconds).
TEST_F(TraceTest, KilledWriterLeavesEverySealedChunk) {
  const fs::path path = file("killed.btrace");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    TraceHeader header;
    header.devices = {glove_device()};
    TraceWriterOptions options;
    options.max_chunk_records = 10;
    TraceWriter writer(path, header, options);
    const Bytes8 report = {1, 2, 3, 4};
    for (int i = 0; i < 95; ++i)
      writer.report_in(0, i, report);
    // The writing thread takes sealed chunks within milliseconds, with no flush asked for.
    std::this_thread::sleep_for(std::chrono::milliseconds(500));
    ::kill(::getpid(), SIGKILL);
    ::_exit(3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFSIGNALED(status));
  TraceReader reader(path);
  const ReadAll all = read_all(reader);
  EXPECT_FALSE(all.error);
  EXPECT_FALSE(all.closed);
  EXPECT_EQ(all.records.size(), 90u);
  EXPECT_EQ(all.records.back().time_ns, 89);
}

// A disk that stops taking the trace (a FIFO nobody reads: its write blocks) never holds up the
// caller of a writer that must not wait: the ring fills, the recording stops and says why, and
// every record call returns. Then the reader drains it and close() ends the writing thread.
TEST_F(TraceTest, AStalledDiskStopsTheRecordingNotTheCaller) {
  const fs::path path = file("stalled.fifo");
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  const int reader = ::open(path.c_str(), O_RDONLY | O_NONBLOCK);
  ASSERT_GE(reader, 0);
  {
    TraceHeader header;
    header.devices = {glove_device()};
    TraceWriterOptions options;
    options.max_chunk_records = 16;
    options.wait_when_full = false;
    TraceWriter writer(path, header, options);
    const Bytes8 report(256, 7);
    // 64 KiB of pipe, then the writing thread blocks in write(); the ring's buffers of 16
    // records of 256 bytes fill after that.
    for (int i = 0; i < 4000; ++i)
      writer.report_in(0, i, report);
    EXPECT_TRUE(writer.failed());
    EXPECT_NE(writer.failure().find("the disk fell behind the recording"), std::string::npos)
        << writer.failure();
    std::thread drain([reader] {
      std::uint8_t buffer[4096];
      for (int quiet = 0; quiet < 200;) {
        if (::read(reader, buffer, sizeof buffer) > 0) {
          quiet = 0;
        } else {
          ++quiet;
          std::this_thread::sleep_for(std::chrono::milliseconds(1));
        }
      }
    });
    EXPECT_THROW(writer.close(), TraceError);  // it says again why the recording stopped
    drain.join();
  }
  ::close(reader);
}

// A writer that is destroyed without close() (an exception unwinding the session) still leaves a
// complete trace; a writer whose file is cut after its last flush leaves what it flushed.
TEST_F(TraceTest, WriterDestroyedWithoutCloseLeavesAReadableTrace) {
  const fs::path path = file("dropped.btrace");
  {
    TraceHeader header;
    header.devices = {glove_device()};
    TraceWriterOptions options;
    options.max_chunk_records = 8;
    TraceWriter writer(path, header, options);
    const Bytes8 report = {9, 9};
    for (int i = 0; i < 20; ++i)
      writer.report_out(0, i, report);
    writer.flush();
    EXPECT_EQ(writer.stats().records, 20u);
    EXPECT_EQ(writer.stats().bytes, fs::file_size(path));
    for (int i = 20; i < 23; ++i)
      writer.report_out(0, i, report);
    // Only sealed chunks are in the file until the writer goes.
    TraceReader partial(path);
    EXPECT_EQ(read_all(partial).records.size(), 20u);
  }
  TraceReader reader(path);
  const ReadAll all = read_all(reader);
  EXPECT_FALSE(all.error);
  EXPECT_TRUE(all.closed);
  EXPECT_EQ(all.records.size(), 23u);
}

TEST_F(TraceTest, ChunksAreSealedByAgeSizeAndPoll) {
  const fs::path path = file("age.btrace");
  TraceHeader header;
  header.devices = {glove_device()};
  TraceWriterOptions options;
  options.max_chunk_records = 1000;
  options.max_chunk_bytes = 200;
  options.max_chunk_age_ns = 5'000'000;
  TraceWriter writer(path, header, options);
  const Bytes8 small = {1};
  writer.report_in(0, 0, small);
  writer.report_in(0, 4'000'000, small);
  EXPECT_EQ(writer.stats().chunks, 0u);
  writer.report_in(0, 5'000'000, small);  // 5 ms after the chunk's first record
  EXPECT_EQ(writer.stats().chunks, 1u);
  writer.report_in(0, 6'000'000, small);
  writer.poll(7'000'000);
  EXPECT_EQ(writer.stats().chunks, 1u);
  writer.poll(11'000'000);
  EXPECT_EQ(writer.stats().chunks, 2u);
  const Bytes8 big(300, 7);
  writer.report_in(0, 12'000'000, big);  // over max_chunk_bytes on its own
  EXPECT_EQ(writer.stats().chunks, 3u);
  writer.close();
  TraceReader reader(path);
  EXPECT_EQ(read_all(reader).records.size(), 5u);
}

TEST_F(TraceTest, ConcurrentWritersInterleaveWholeRecords) {
  const fs::path path = file("threads.btrace");
  TraceHeader header;
  header.devices = {glove_device(), glove_device(), glove_device(), glove_device()};
  TraceWriterOptions options;
  options.max_chunk_records = 64;
  {
    TraceWriter writer(path, header, options);
    std::vector<std::thread> threads;
    for (std::uint16_t d = 0; d < 4; ++d) {
      threads.emplace_back([&writer, d] {
        for (int i = 0; i < 2000; ++i) {
          const Bytes8 r = {static_cast<std::uint8_t>(d), static_cast<std::uint8_t>(i)};
          writer.report_in(d, i, r);
        }
      });
    }
    for (auto& t : threads)
      t.join();
  }
  TraceReader reader(path);
  const ReadAll all = read_all(reader);
  ASSERT_FALSE(all.error);
  ASSERT_EQ(all.records.size(), 8000u);
  std::vector<int> next(4, 0);
  for (const TraceRecord& r : all.records) {
    ASSERT_EQ(r.payload[0], r.device);
    EXPECT_EQ(r.time_ns, next[r.device]++);  // each device's records stay in order
  }
}

TEST_F(TraceTest, GuardConfigurationTravelsInTheTrace) {
  ForceGuardConfig c;
  c.ramp_in = std::chrono::milliseconds(40);
  c.engage_threshold_N = 0.25;
  c.watchdog_auto_rearm = false;
  const ForceGuardConfig back = force_guard_config_from_json(force_guard_config_json(c));
  EXPECT_EQ(back.ramp_in, c.ramp_in);
  EXPECT_EQ(back.engage_threshold_N, 0.25);
  EXPECT_FALSE(back.watchdog_auto_rearm);
  EXPECT_EQ(back.period, c.period);
  const ForceGuardConfig fallback = force_guard_config_from_json("not json", c);
  EXPECT_EQ(fallback.ramp_in, c.ramp_in);
  EXPECT_THROW(force_guard_config_from_json(R"({"force_guard":{"ramp_in_ns":"x"}})"), TraceError);
}

TEST_F(TraceTest, ReplayTransportFeedsInputsInVirtualTime) {
  VirtualClock clock(std::chrono::milliseconds(10));
  ReplayTransport t(DeviceDescriptor{}, clock);
  const Bytes8 a = {1}, b = {2};
  t.push_input(std::chrono::milliseconds(10), a);
  t.push_input(std::chrono::milliseconds(15), b);
  EXPECT_EQ(t.read(std::chrono::microseconds(0)), a);
  EXPECT_EQ(t.read(std::chrono::microseconds(0)), std::nullopt);  // not due, the clock stays
  EXPECT_EQ(clock.now(), std::chrono::milliseconds(10));
  EXPECT_EQ(t.read(std::chrono::milliseconds(2)), std::nullopt);  // waits 2 ms in vain
  EXPECT_EQ(clock.now(), std::chrono::milliseconds(12));
  EXPECT_EQ(t.read(std::chrono::milliseconds(5)), b);  // due at 15 ms: the clock jumps there
  EXPECT_EQ(clock.now(), std::chrono::milliseconds(15));
  t.write(a);
  const auto written = t.take_written();
  ASSERT_EQ(written.size(), 1u);
  EXPECT_EQ(written[0].time, std::chrono::milliseconds(15));
  auto link = t.link();
  link->disconnect();
  EXPECT_THROW(t.read(std::chrono::microseconds(0)), DeviceDisconnected);
  EXPECT_THROW(t.write(a), DeviceDisconnected);
  EXPECT_TRUE(link->take_written().empty());
}

TEST_F(TraceTest, RecordingTransportRecordsBothDirectionsAndTheDisconnect) {
  const fs::path path = file("recording.btrace");
  VirtualClock clock(std::chrono::milliseconds(5));
  DeviceDescriptor d;
  d.product = "pipe";
  d.path = "virtual:pipe";
  VirtualPair pair = make_virtual_pair(d);
  {
    TraceHeader header;
    header.devices = {to_trace_device(pair.host->descriptor())};
    TraceWriter writer(path, header);
    RecordingTransport rec(std::move(pair.host), writer, 0, clock);
    const Bytes8 in = {0xA1, 0x02}, out = {0x05, 0x06, 0x07};
    pair.device->write(in);
    clock.advance(std::chrono::microseconds(250));
    EXPECT_EQ(rec.read(std::chrono::microseconds(0)), in);
    rec.write(out);
    EXPECT_EQ(pair.device->read(std::chrono::microseconds(0)), out);
    pair.device->disconnect();
    EXPECT_THROW(rec.read(std::chrono::microseconds(0)), DeviceDisconnected);
    EXPECT_THROW(rec.write(out), DeviceDisconnected);  // lost: not recorded again
    EXPECT_TRUE(rec.disconnected());
  }
  TraceReader reader(path);
  const ReadAll all = read_all(reader);
  ASSERT_EQ(all.records.size(), 4u);
  EXPECT_EQ(all.records[0].type, TraceRecordType::kConnect);
  EXPECT_EQ(all.records[1].type, TraceRecordType::kReportIn);
  EXPECT_EQ(all.records[1].time_ns, 5'250'000);
  EXPECT_EQ(all.records[1].payload, (Bytes8{0xA1, 0x02}));
  EXPECT_EQ(all.records[2].type, TraceRecordType::kReportOut);
  EXPECT_EQ(all.records[2].payload, (Bytes8{0x05, 0x06, 0x07}));
  EXPECT_EQ(all.records[3].type, TraceRecordType::kDisconnect);
  EXPECT_EQ(to_device_descriptor(reader.devices()[0]).path, "virtual:pipe");
}

TEST_F(TraceTest, SimulatedGloveSessionReplaysByteForByte) {
  const fs::path path = file("glove.btrace");
  testing::SimSessionOptions options;
  options.unplug_at = std::chrono::milliseconds(100);
  options.writer.max_chunk_records = 64;
  const std::size_t commands = testing::record_sim_session(path, options);
  EXPECT_GT(commands, 150u);
  TraceReader reader(path);
  const TraceReplayResult r = replay_trace(reader);
  EXPECT_TRUE(r.passed()) << (r.mismatch ? r.mismatch->reason : std::string("trace error"));
  EXPECT_EQ(r.mismatches, 0u);
  EXPECT_EQ(r.unverified_outputs, 0u);
  ASSERT_EQ(r.devices.size(), 2u);
  const ReplayDeviceStats& glove = r.devices[0];
  EXPECT_EQ(glove.device.driver, "hid-glove");
  EXPECT_EQ(glove.force_commands, commands);
  EXPECT_EQ(glove.connects, 2u);
  EXPECT_EQ(glove.disconnects, 1u);
  EXPECT_GT(glove.reports_in, 150u);
  EXPECT_GT(glove.reports_out_recorded, commands);  // the vibration channel is a report of its own
  EXPECT_EQ(glove.reports_out_matched, glove.reports_out_recorded);
  EXPECT_EQ(glove.reports_out_replayed, glove.reports_out_recorded);
  EXPECT_EQ(r.devices[1].device.driver, "hid-tracker");
  EXPECT_GT(r.devices[1].reports_in, 90u);
  // The device first, the trace after: a force command's record follows the output report it
  // made, at the same time (while the glove is connected).
  TraceReader again(path);
  std::optional<TraceRecord> previous;
  std::size_t after_their_report = 0;
  while (auto record = again.next()) {
    if (record->device != 0 || record->type == TraceRecordType::kNote) continue;
    if (record->type == TraceRecordType::kForceCommand && previous &&
        previous->type == TraceRecordType::kReportOut && previous->time_ns == record->time_ns)
      ++after_their_report;
    previous = record;
  }
  EXPECT_GE(after_their_report, commands * 9 / 10) << "of " << commands;
}

// A live clock moves between the transport's stamp on a report and the driver's. With the glove
// reporting just slower than the silence watchdog's 50 ms, each watchdog decision falls within
// those microseconds: the replay's guard hears each answer at the recorded time, and so must the
// live one, or the two zero different commands.
TEST_F(TraceTest, AClockThatMovesOnEveryReadingReplaysTheSilenceWatchdogAlike) {
  for (const double rate_hz : {19.99, 19.999}) {
    SCOPED_TRACE(rate_hz);
    const fs::path path = file("ticking.btrace");
    testing::SimSessionOptions options;
    options.duration = std::chrono::milliseconds(400);
    options.glove_rate_hz = rate_hz;
    options.tick_per_reading = std::chrono::microseconds(3);
    options.tracker = false;
    testing::record_sim_session(path, options);
    TraceReader reader(path);
    const TraceReplayResult r = replay_trace(reader);
    EXPECT_TRUE(r.passed()) << (r.mismatch ? r.mismatch->reason : std::string("trace error"));
    EXPECT_EQ(r.mismatches, 0u);
    ASSERT_EQ(r.devices.size(), 1u);
    EXPECT_GT(r.devices[0].reports_in, 5u);
  }
}

// The recorded session, with one byte of one output report changed (and the chunk's checksum
// recomputed by writing it again): the replay names that report.
TEST_F(TraceTest, ReplayFindsAFlippedOutputByte) {
  const fs::path path = file("glove.btrace");
  testing::record_sim_session(path);
  const fs::path edited = file("edited.btrace");
  std::uint64_t target = 0;
  std::int64_t target_time = 0;
  Bytes8 original;
  {
    TraceReader reader(path);
    TraceWriter writer(edited, reader.header());
    std::uint64_t index = 0;
    std::uint64_t outs = 0;
    while (auto r = reader.next()) {
      if (r->type == TraceRecordType::kDeviceAdded) {
        writer.add_device(r->time_ns, decode_device(r->payload, "x"));
        ++index;
        continue;
      }
      if (r->type == TraceRecordType::kReportOut && r->device == 0 && ++outs == 120) {
        target = index;
        target_time = r->time_ns;
        original = r->payload;
        r->payload.back() ^= 0x01;
      }
      writer.append(r->type, r->device, r->time_ns, r->payload);
      ++index;
    }
    writer.close();
  }
  ASSERT_FALSE(original.empty());
  TraceReader reader(edited);
  const TraceReplayResult r = replay_trace(reader);
  EXPECT_FALSE(r.passed());
  EXPECT_EQ(r.mismatches, 1u);
  ASSERT_TRUE(r.mismatch);
  EXPECT_EQ(r.mismatch->device, 0u);
  EXPECT_EQ(r.mismatch->record_index, target);
  EXPECT_EQ(r.mismatch->output_index, 119u);
  EXPECT_EQ(r.mismatch->time_ns, target_time);
  EXPECT_EQ(r.mismatch->reason, "bytes differ");
  ASSERT_TRUE(r.mismatch->expected && r.mismatch->actual);
  EXPECT_EQ(*r.mismatch->actual, original);
  Bytes8 flipped = original;
  flipped.back() ^= 0x01;
  EXPECT_EQ(*r.mismatch->expected, flipped);
}

// A damaged copy replays everything before its bad chunk, then reports the chunk.
TEST_F(TraceTest, DamagedTraceReplaysItsGoodPrefix) {
  const fs::path path = file("glove.btrace");
  testing::SimSessionOptions options;
  options.writer.max_chunk_records = 50;
  testing::record_sim_session(path, options);
  const Bytes8 good = read_bytes(path);
  const Layout l = layout_of(good);
  ASSERT_GT(l.chunks.size(), 6u);
  const std::size_t bad_chunk = l.chunks.size() / 2;
  for (const bool truncate : {false, true}) {
    Bytes8 bad = good;
    if (truncate) {
      bad.resize(l.chunks[bad_chunk].offset + 40);
    } else {
      bad[l.chunks[bad_chunk].offset + 60] ^= 0x10;
    }
    TraceReader reader(bad, "damaged.btrace");
    const TraceReplayResult r = replay_trace(reader);
    ASSERT_TRUE(r.trace_error);
    EXPECT_EQ(r.trace_error->chunk(), bad_chunk);
    EXPECT_EQ(r.trace_error->offset(), l.chunks[bad_chunk].offset);
    EXPECT_EQ(r.trace_error->truncated(), truncate);
    EXPECT_EQ(r.records, records_before(l, l.chunks[bad_chunk].offset));
    EXPECT_EQ(r.mismatches, 0u);
    EXPECT_FALSE(r.passed());
  }
}

TEST_F(TraceTest, SummaryCountsDevicesReportsAndChunks) {
  const fs::path path = file("glove.btrace");
  testing::SimSessionOptions options;
  options.writer.max_chunk_records = 100;
  const std::size_t commands = testing::record_sim_session(path, options);
  TraceReader reader(path);
  const TraceSummary s = summarize_trace(reader);
  EXPECT_FALSE(s.first_bad_chunk);
  EXPECT_TRUE(s.closed_by_writer);
  EXPECT_TRUE(s.session_ended);
  ASSERT_EQ(s.devices.size(), 2u);
  EXPECT_EQ(s.force_commands, commands);
  EXPECT_EQ(s.reports_in, s.devices[0].reports_in + s.devices[1].reports_in);
  EXPECT_EQ(s.devices[1].reports_out, 0u);
  EXPECT_NEAR(s.duration_s(), 0.199, 0.002);
  EXPECT_EQ(s.good_bytes, fs::file_size(path));
  EXPECT_EQ(s.chunks, (s.records + 99) / 100 + 1);
}

TEST_F(TraceTest, CutsAreValidTracesAndAPrefixCutReplays) {
  const fs::path path = file("glove.btrace");
  testing::SimSessionOptions options;
  options.writer.max_chunk_records = 40;
  testing::record_sim_session(path, options);

  // A prefix: replays with no mismatch; what the drivers wrote after the cut is unverified.
  const fs::path prefix = file("prefix.btrace");
  {
    TraceReader reader(path);
    TraceCutOptions cut;
    cut.to_s = 0.1;
    const TraceCutResult c = cut_trace(reader, prefix, cut);
    EXPECT_FALSE(c.input_error);
    EXPECT_LT(c.records_read, summarize_trace(*std::make_unique<TraceReader>(path)).records);
    EXPECT_EQ(c.records_written, c.records_read);  // less the first one after, plus the note
  }
  {
    TraceReader reader(prefix);
    const TraceReplayResult r = replay_trace(reader);
    EXPECT_TRUE(r.passed()) << (r.mismatch ? r.mismatch->reason : "trace error");
    EXPECT_LE(r.last_time_ns - r.first_time_ns, 100'000'000);
    EXPECT_GT(r.unverified_outputs, 0u);
  }
  // A middle window by time and by chunk: valid traces whose devices connect at the window.
  for (const bool by_chunk : {false, true}) {
    const fs::path middle = file(by_chunk ? "chunks.btrace" : "middle.btrace");
    TraceCutOptions cut;
    if (by_chunk) {
      cut.from_chunk = 3;
      cut.to_chunk = 5;
    } else {
      cut.from_s = 0.05;
      cut.to_s = 0.08;
    }
    TraceReader reader(path);
    cut_trace(reader, middle, cut);
    TraceReader back(middle);
    const TraceSummary s = summarize_trace(back);
    EXPECT_FALSE(s.first_bad_chunk);
    EXPECT_FALSE(s.session_ended);
    ASSERT_EQ(s.devices.size(), 2u);
    EXPECT_EQ(s.devices[0].connects, 1u);
    EXPECT_EQ(s.notes, 1u);
    if (by_chunk) {
      EXPECT_LE(s.records, 3u * 40u + 5u);  // + note, connects, devices
    } else {
      EXPECT_LE(s.duration_s(), 0.030 + 1e-9);
    }
  }
  // A damaged input: the cut keeps its good prefix and is itself whole.
  Bytes8 bad = read_bytes(path);
  bad[layout_of(bad).chunks[4].offset + 30] ^= 0xFF;
  write_bytes(file("bad.btrace"), bad);
  TraceReader damaged(file("bad.btrace"));
  const TraceCutResult c = cut_trace(damaged, file("repaired.btrace"), {});
  ASSERT_TRUE(c.input_error);
  EXPECT_EQ(c.input_error->chunk(), 4u);
  TraceReader repaired(file("repaired.btrace"));
  const TraceSummary s = summarize_trace(repaired);
  EXPECT_FALSE(s.first_bad_chunk);
  EXPECT_EQ(s.records, 4u * 40u + 1u);  // four chunks and the cut's note
  EXPECT_THROW(
      {
        TraceReader same(file("repaired.btrace"));
        cut_trace(same, file("repaired.btrace"), {});
      },
      TraceError);
}

}  // namespace
}  // namespace bisturi::devices
