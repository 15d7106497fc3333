// Trace write throughput (MB/s and records/s) and read throughput: records of typical sizes
// appended to a TraceWriter on one thread, chunks sealed (CRC-32) and written by the writer's
// own thread as in a live session; the session's 1 kHz glove step (one input report, one force command, two output
// reports); and TraceReader streaming the result back. Files go to $TMPDIR (default /tmp);
// rates are per wall-clock second (page-cache writes, no fsync).
// Run by hand (build/bin/trace_bench).

#include <benchmark/benchmark.h>

#include <unistd.h>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <string>
#include <vector>

#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/trace/trace_writer.h"

namespace {

namespace bd = bisturi::devices;
namespace fs = std::filesystem;

fs::path bench_file(const char* name) {
  return fs::temp_directory_path() /
         ("bisturi_trace_bench_" + std::to_string(::getpid()) + "_" + name + ".btrace");
}

bd::TraceHeader header() {
  bd::TraceHeader h;
  h.producer = "trace_bench";
  bd::TraceDevice glove;
  glove.kind = "hid";
  glove.product = "bench glove";
  glove.driver = "hid-glove";
  h.devices = {glove};
  return h;
}

constexpr int kRecordsPerIteration = 100'000;

// Records of one payload size (state.range(0) bytes) in chunks of state.range(1) records.
void BM_TraceWriteRecords(benchmark::State& state) {
  const fs::path path = bench_file("records");
  const std::vector<std::uint8_t> report(static_cast<std::size_t>(state.range(0)), 0x5A);
  bd::TraceWriterOptions options;
  options.max_chunk_records = static_cast<std::size_t>(state.range(1));
  std::uint64_t bytes = 0;
  for (auto _ : state) {
    bd::TraceWriter writer(path, header(), options);
    for (int i = 0; i < kRecordsPerIteration; ++i)
      writer.report_in(0, i * 1000, report);
    writer.close();
    bytes += writer.stats().bytes;
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.SetItemsProcessed(state.iterations() * kRecordsPerIteration);
  fs::remove(path);
}
BENCHMARK(BM_TraceWriteRecords)
    ->ArgNames({"payload_B", "chunk_records"})
    ->Args({16, 4096})
    ->Args({64, 4096})
    ->Args({256, 4096})
    ->Args({64, 64})
    ->Unit(benchmark::kMillisecond)
    ->UseRealTime();

// One haptic-loop step of the simulated glove as the session records it: a 64-byte input
// report, a force command of 6 values, two output reports (PID forces, vibration).
void BM_TraceWriteGloveStep(benchmark::State& state) {
  const fs::path path = bench_file("glove");
  const std::vector<std::uint8_t> in(64, 0x11), pid(11, 0x22), vib(3, 0x33);
  const double forces[6] = {0.1, 0.2, 0.3, 0.4, 0.5, 0.0};
  std::uint64_t bytes = 0;
  for (auto _ : state) {
    bd::TraceWriter writer(path, header());
    for (int i = 0; i < kRecordsPerIteration / 4; ++i) {
      const std::int64_t t = std::int64_t{i} * 1'000'000;
      writer.report_in(0, t, in);
      writer.force_command(0, t + 1000, forces);
      writer.report_out(0, t + 2000, pid);
      writer.report_out(0, t + 2100, vib);
    }
    writer.close();
    bytes += writer.stats().bytes;
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(bytes));
  state.SetItemsProcessed(state.iterations() * kRecordsPerIteration);
  state.counters["ns_per_step"] =
      benchmark::Counter(static_cast<double>(state.iterations() * kRecordsPerIteration / 4),
                         benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  fs::remove(path);
}
BENCHMARK(BM_TraceWriteGloveStep)->Unit(benchmark::kMillisecond)->UseRealTime();

// Streaming the 64-byte records back (checksums, decoding, one allocation per record).
void BM_TraceRead(benchmark::State& state) {
  const fs::path path = bench_file("read");
  {
    const std::vector<std::uint8_t> report(64, 0x5A);
    bd::TraceWriter writer(path, header());
    for (int i = 0; i < kRecordsPerIteration; ++i)
      writer.report_in(0, i * 1000, report);
  }
  const auto size = fs::file_size(path);
  for (auto _ : state) {
    bd::TraceReader reader(path);
    std::uint64_t n = 0;
    while (auto r = reader.next())
      n += r->payload.size();
    benchmark::DoNotOptimize(n);
  }
  state.SetBytesProcessed(static_cast<std::int64_t>(size) * state.iterations());
  state.SetItemsProcessed(state.iterations() * kRecordsPerIteration);
  fs::remove(path);
}
BENCHMARK(BM_TraceRead)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
