#include "trace_command.h"

#include "number_checks.h"

#include "hex_bytes.h"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <filesystem>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>

#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/devices/trace/trace_replay.h"
#include "bisturi/devices/trace/trace_tools.h"

namespace bisturi::cli {

namespace {

using devices::TraceCorruptError;

constexpr int kExitBadChunk = 2;
constexpr int kExitMismatch = 3;

std::string hex16(std::uint16_t v) {
  char text[8];
  std::snprintf(text, sizeof text, "%04x", v);
  return text;
}

nlohmann::json bad_chunk_json(const std::optional<TraceCorruptError>& e) {
  if (!e) return nullptr;
  return {{"chunk", e->chunk() ? nlohmann::json(*e->chunk()) : nlohmann::json(nullptr)},
          {"offset", e->offset()},
          {"truncated", e->truncated()},
          {"reason", e->reason()},
          {"message", e->what()}};
}

nlohmann::json device_json(std::size_t index, const devices::TraceDevice& d) {
  return {{"index", index},
          {"kind", d.kind},
          {"vendor_id", hex16(d.vendor_id)},
          {"product_id", hex16(d.product_id)},
          {"serial", d.serial},
          {"product", d.product},
          {"path", d.path},
          {"driver", d.driver},
          {"report_descriptor_bytes", d.report_descriptor.size()}};
}

std::string device_line(std::size_t index, const devices::TraceDevice& d) {
  return "device " + std::to_string(index) + ": " + d.product + " (" + d.kind + " " +
         hex16(d.vendor_id) + ":" + hex16(d.product_id) + ", serial " + d.serial + ", driver " +
         (d.driver.empty() ? "?" : d.driver) + ")";
}

double seconds(std::int64_t ns) {
  return static_cast<double>(ns) * 1e-9;
}

}  // namespace

void add_trace_command(CLI::App& app, TraceOptions& options, int (*&run)(const TraceOptions&)) {
  CLI::App* trace = app.add_subcommand(
      "trace",
      "inspect, replay, cut and dump device traces (reports in and out, force commands), and "
      "read what their forces did (trace forces)");
  trace->require_subcommand(1);

  CLI::App* inspect = trace->add_subcommand(
      "inspect",
      "report a trace's devices, duration, chunks and reports, and its first bad chunk (exit "
      "status 2 when it has one)");
  inspect->add_option("TRACE", options.input, "trace file")->required()->check(CLI::ExistingFile);
  inspect->add_flag("--json", options.json, "write the report as one JSON object on stdout");
  inspect->callback([&run] { run = run_trace_inspect; });

  CLI::App* replay = trace->add_subcommand(
      "replay",
      "replay a trace through the same drivers and force guard in virtual time and compare the "
      "output reports byte for byte (exit status 0: pass, 3: mismatch, 2: bad chunk)");
  replay->add_option("TRACE", options.input, "trace file")->required()->check(CLI::ExistingFile);
  replay->add_flag("--json", options.json, "write the result as one JSON object on stdout");
  replay->callback([&run] { run = run_trace_replay; });

  CLI::App* cut = trace->add_subcommand(
      "cut",
      "write part of a trace (a time window and/or a chunk range) as a new, valid trace; a "
      "damaged trace cut without a window keeps everything before its bad chunk");
  cut->add_option("TRACE", options.input, "trace file")->required()->check(CLI::ExistingFile);
  cut->add_option("--out", options.output, "trace to write")->required();
  cut->add_option("--from", options.from_s, "seconds after the trace's first record")
      ->check(kNonNegative);
  cut->add_option("--to", options.to_s, "seconds after the trace's first record")
      ->check(kNonNegative);
  cut->add_option("--from-chunk", options.from_chunk, "first chunk to keep");
  cut->add_option("--to-chunk", options.to_chunk, "last chunk to keep");
  cut->add_flag("--json", options.json, "write a JSON summary on stdout");
  cut->callback([&run] { run = run_trace_cut; });

  CLI::App* dump = trace->add_subcommand(
      "dump",
      "print every record decoded: time, device, direction, the report's fields (through the "
      "recorded driver and, for HID, the report descriptor), force commands as vectors per "
      "channel (exit 2 at a bad chunk, after the records before it)");
  dump->add_option("TRACE", options.input, "trace file")->required()->check(CLI::ExistingFile);
  dump->add_option("--device", options.device,
                   "only this device: its index, driver name, serial or product");
  dump->add_flag("--json", options.json, "write one JSON object on stdout");
  dump->callback([&run] { run = run_trace_dump; });

  CLI::App* forces = trace->add_subcommand(
      "forces",
      "what the recorded force commands did, per channel: the largest force, the impulse (force "
      "over time), commands at the limit, the largest change in one tick against the device's "
      "rate limit, reversals and chatter (fault zeros counted apart)");
  forces->add_option("TRACE", options.input, "trace file")->required()->check(CLI::ExistingFile);
  forces->add_option("--limit-N", options.limit_N,
                     "the session's force limit (the scene's max_force_N), when below a "
                     "channel's own")
      ->check(kPositive);
  forces->add_flag("--json", options.json, "write one JSON object on stdout");
  forces->callback([&run] { run = run_trace_forces; });
}

int run_trace_inspect(const TraceOptions& options) {
  std::optional<devices::TraceReader> reader;
  try {
    reader.emplace(options.input);
  } catch (const TraceCorruptError& e) {
    // A bad header is the first bad chunk of all: reported like one.
    if (options.json) {
      const nlohmann::json j = {
          {"file", options.input}, {"ok", false}, {"first_bad_chunk", bad_chunk_json(e)}};
      std::cout << j.dump(2) << "\n";
    } else {
      std::cout << options.input << ": bad file header\n  " << e.what() << "\n";
    }
    return kExitBadChunk;
  }
  const devices::TraceSummary s = devices::summarize_trace(*reader);
  const auto file_bytes = std::filesystem::file_size(options.input);
  if (options.json) {
    nlohmann::json devs = nlohmann::json::array();
    for (std::size_t i = 0; i < s.devices.size(); ++i) {
      const auto& d = s.devices[i];
      nlohmann::json j = device_json(i, d.device);
      j["reports_in"] = d.reports_in;
      j["reports_out"] = d.reports_out;
      j["bytes_in"] = d.bytes_in;
      j["bytes_out"] = d.bytes_out;
      j["force_commands"] = d.force_commands;
      j["connects"] = d.connects;
      j["disconnects"] = d.disconnects;
      devs.push_back(std::move(j));
    }
    const nlohmann::json j = {
        {"file", options.input},
        {"ok", !s.first_bad_chunk},
        {"format_version",
         std::to_string(s.header.version_major) + "." + std::to_string(s.header.version_minor)},
        {"producer", s.header.producer},
        {"config", s.header.config},
        {"devices", devs},
        {"duration_s", s.duration_s()},
        {"first_time_ns", s.first_time_ns ? nlohmann::json(*s.first_time_ns) : nullptr},
        {"last_time_ns", s.last_time_ns ? nlohmann::json(*s.last_time_ns) : nullptr},
        {"chunks", s.chunks},
        {"records", s.records},
        {"reports_in", s.reports_in},
        {"reports_out", s.reports_out},
        {"force_commands", s.force_commands},
        {"notes", s.notes},
        {"skipped_records", s.skipped_records},
        {"closed_by_writer", s.closed_by_writer},
        {"session_ended", s.session_ended},
        {"good_bytes", s.good_bytes},
        {"file_bytes", file_bytes},
        {"first_bad_chunk", bad_chunk_json(s.first_bad_chunk)}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << options.input << " (trace format " << s.header.version_major << "."
              << s.header.version_minor << ", " << file_bytes << " bytes"
              << (s.header.producer.empty() ? "" : ", written by " + s.header.producer) << ")\n";
    for (std::size_t i = 0; i < s.devices.size(); ++i) {
      const auto& d = s.devices[i];
      std::cout << "  " << device_line(i, d.device) << "\n    " << d.reports_in << " reports in, "
                << d.reports_out << " out, " << d.force_commands << " force commands, "
                << d.connects << " connects, " << d.disconnects << " disconnects\n";
    }
    std::cout << "  duration " << s.duration_s() << " s, " << s.chunks << " chunks, " << s.records
              << " records (" << s.reports_in << " reports in, " << s.reports_out << " out, "
              << s.force_commands << " force commands)\n";
    if (s.first_bad_chunk) {
      std::cout << "  first bad chunk: " << s.first_bad_chunk->what() << "\n";
    } else if (!s.closed_by_writer) {
      std::cout << "  the writer did not close the trace (killed?): it ends after its last "
                   "whole chunk\n";
    } else if (!s.session_ended) {
      std::cout << "  a cut: the recorded session went on after it\n";
    }
  }
  return s.first_bad_chunk ? kExitBadChunk : 0;
}

int run_trace_replay(const TraceOptions& options) {
  devices::TraceReader reader(options.input);
  const devices::TraceReplayResult r = devices::replay_trace(reader);
  const std::int64_t origin = r.first_time_ns;
  std::uint64_t matched = 0;
  for (const auto& d : r.devices)
    matched += d.reports_out_matched;
  if (options.json) {
    nlohmann::json devs = nlohmann::json::array();
    for (std::size_t i = 0; i < r.devices.size(); ++i) {
      const auto& d = r.devices[i];
      nlohmann::json j = device_json(i, d.device);
      j["reports_in"] = d.reports_in;
      j["reports_out_recorded"] = d.reports_out_recorded;
      j["reports_out_replayed"] = d.reports_out_replayed;
      j["reports_out_matched"] = d.reports_out_matched;
      j["force_commands"] = d.force_commands;
      j["malformed_reports"] = d.malformed_reports;
      devs.push_back(std::move(j));
    }
    nlohmann::json mismatch = nullptr;
    if (r.mismatch) {
      const auto& m = *r.mismatch;
      mismatch = {{"device", m.device},
                  {"record_index", m.record_index},
                  {"output_index", m.output_index},
                  {"time_ns", m.time_ns},
                  {"time_s", seconds(m.time_ns - origin)},
                  {"reason", m.reason},
                  {"expected", m.expected ? nlohmann::json(hex_bytes(*m.expected)) : nullptr},
                  {"actual", m.actual ? nlohmann::json(hex_bytes(*m.actual)) : nullptr}};
    }
    const nlohmann::json j = {{"file", options.input},
                              {"passed", r.passed()},
                              {"records", r.records},
                              {"duration_s", seconds(r.last_time_ns - r.first_time_ns)},
                              {"outputs_matched", matched},
                              {"mismatches", r.mismatches},
                              {"unverified_outputs", r.unverified_outputs},
                              {"first_mismatch", mismatch},
                              {"trace_error", bad_chunk_json(r.trace_error)},
                              {"devices", devs}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << (r.passed() ? "PASS" : "FAIL") << ": " << options.input << ": " << r.devices.size()
              << " devices, " << r.records << " records over "
              << seconds(r.last_time_ns - r.first_time_ns) << " s replayed; " << matched
              << " output reports match";
    if (r.unverified_outputs > 0) {
      std::cout << " (" << r.unverified_outputs << " written after the recording ends)";
    }
    std::cout << "\n";
    if (r.mismatch) {
      const auto& m = *r.mismatch;
      std::cout << "  first mismatch (" << r.mismatches << " in all): device " << m.device
                << ", record " << m.record_index << ", output report " << m.output_index
                << ", t = " << seconds(m.time_ns - origin) << " s: " << m.reason << "\n"
                << "    expected: " << (m.expected ? hex_bytes(*m.expected) : "(none)") << "\n"
                << "    actual:   " << (m.actual ? hex_bytes(*m.actual) : "(none)") << "\n";
    }
    if (r.trace_error) {
      std::cout << "  bad chunk: " << r.trace_error->what() << "\n  (the " << r.records
                << " records before it were replayed)\n";
    }
  }
  if (r.mismatch) return kExitMismatch;
  return r.trace_error ? kExitBadChunk : 0;
}

int run_trace_cut(const TraceOptions& options) {
  devices::TraceReader reader(options.input);
  devices::TraceCutOptions cut;
  cut.from_s = options.from_s;
  cut.to_s = options.to_s;
  cut.from_chunk = options.from_chunk;
  cut.to_chunk = options.to_chunk;
  const devices::TraceCutResult r = devices::cut_trace(reader, options.output, cut);
  if (options.json) {
    const nlohmann::json j = {{"file", options.input},
                              {"out", options.output},
                              {"records_read", r.records_read},
                              {"records_written", r.records_written},
                              {"chunks_written", r.chunks_written},
                              {"input_error", bad_chunk_json(r.input_error)}};
    std::cout << j.dump(2) << "\n";
  } else {
    std::cout << "wrote " << options.output << ": " << r.records_written << " records in "
              << r.chunks_written << " chunks\n";
    if (r.input_error) {
      std::cout << "  the input ends with a bad chunk, the cut holds what came before it:\n  "
                << r.input_error->what() << "\n";
    }
  }
  return 0;
}

}  // namespace bisturi::cli
