#pragma once
// `bisturi trace inspect|replay|cut|dump|forces`: device traces on the command line.
//   inspect TRACE [--json]   devices, duration, chunks, reports in/out, the first bad chunk (exit
//                            status 2 when there is one)
//   replay TRACE [--json]    replays through the same drivers and force guard in virtual time and
//                            compares the output reports (exit 0: pass, 3: mismatch, 2: bad chunk)
//   cut TRACE --out FILE [--from S] [--to S] [--from-chunk N] [--to-chunk N] [--json]
//   dump TRACE [--device NAME] [--json]
//                            every record decoded: time, device, direction, report fields, force
//                            commands as vectors (exit status 2 at a bad chunk)
//   forces TRACE [--limit-N F] [--json]
//                            per force channel: the largest force, the impulse, ticks at the
//                            limit, the largest change in one tick against the device's rate
//                            limit, chatter

#include <cstdint>
#include <optional>
#include <string>

namespace CLI {
class App;
}

namespace bisturi::cli {

struct TraceOptions {
  std::string input;
  std::string output;
  std::string device;  // dump: index, driver, serial or product
  bool json = false;
  std::optional<double> from_s;
  std::optional<double> to_s;
  std::optional<std::uint64_t> from_chunk;
  std::optional<std::uint64_t> to_chunk;
  std::optional<double> limit_N;  // forces: the session's limit, when below the channels' own
};

/// Adds the `trace` command with its sub-commands; `run` is set to the one parsed.
void add_trace_command(CLI::App& app, TraceOptions& options, int (*&run)(const TraceOptions&));

int run_trace_inspect(const TraceOptions& options);
int run_trace_replay(const TraceOptions& options);
int run_trace_cut(const TraceOptions& options);
int run_trace_dump(const TraceOptions& options);
int run_trace_forces(const TraceOptions& options);

}  // namespace bisturi::cli
