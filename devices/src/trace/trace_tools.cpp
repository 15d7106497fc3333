#include "bisturi/devices/trace/trace_tools.h"

#include <cmath>
#include <system_error>

namespace bisturi::devices {

TraceSummary summarize_trace(TraceReader& reader) {
  TraceSummary s;
  s.file = reader.name();
  s.header = reader.header();
  const auto device = [&s, &reader](std::uint16_t d) -> TraceDeviceSummary& {
    while (s.devices.size() < reader.devices().size()) {
      TraceDeviceSummary summary;
      summary.device = reader.devices()[s.devices.size()];
      s.devices.push_back(std::move(summary));
    }
    return s.devices.at(d);
  };
  for (;;) {
    std::optional<TraceRecord> r;
    try {
      r = reader.next();
    } catch (const TraceCorruptError& e) {
      s.first_bad_chunk = e;
      break;
    }
    if (!r) break;
    ++s.records;
    if (!s.first_time_ns) s.first_time_ns = r->time_ns;
    s.last_time_ns = r->time_ns;
    if (r->type == TraceRecordType::kNote) {
      ++s.notes;
      continue;
    }
    TraceDeviceSummary& d = device(r->device);
    switch (r->type) {
      case TraceRecordType::kReportIn:
        ++s.reports_in;
        ++d.reports_in;
        d.bytes_in += r->payload.size();
        break;
      case TraceRecordType::kReportOut:
        ++s.reports_out;
        ++d.reports_out;
        d.bytes_out += r->payload.size();
        break;
      case TraceRecordType::kForceCommand:
        ++s.force_commands;
        ++d.force_commands;
        break;
      case TraceRecordType::kConnect:
        ++d.connects;
        break;
      case TraceRecordType::kDisconnect:
        ++d.disconnects;
        break;
      case TraceRecordType::kDeviceAdded:
      case TraceRecordType::kNote:
        break;
    }
  }
  if (!reader.devices().empty()) device(0);  // devices without records are listed too
  s.chunks = reader.chunks_read();
  s.skipped_records = reader.records_skipped();
  s.good_bytes = reader.offset();
  s.closed_by_writer = reader.closed_by_writer();
  s.session_ended = reader.session_ended();
  return s;
}

TraceCutResult cut_trace(TraceReader& reader, const std::filesystem::path& out,
                         const TraceCutOptions& options) {
  std::error_code ec;
  if (std::filesystem::exists(out, ec) && std::filesystem::equivalent(reader.name(), out, ec)) {
    throw TraceError(out.string() + ": the cut would overwrite its input");
  }
  const auto to_ns = [](double s) { return static_cast<std::int64_t>(std::llround(s * 1e9)); };
  TraceHeader header = reader.header();
  std::string note = "cut of " + reader.name() + ":";
  if (options.from_s) note += " from " + std::to_string(*options.from_s) + " s";
  if (options.to_s) note += " to " + std::to_string(*options.to_s) + " s";
  if (options.from_chunk) note += " from chunk " + std::to_string(*options.from_chunk);
  if (options.to_chunk) note += " to chunk " + std::to_string(*options.to_chunk);

  TraceWriter writer(out, header, options.writer);
  TraceCutResult result;
  std::vector<bool> connected(reader.devices().size(), false);
  std::optional<std::int64_t> start;
  bool window_open = false;
  std::vector<TraceDevice> pending_devices;
  for (;;) {
    std::optional<TraceRecord> r;
    try {
      r = reader.next();
    } catch (const TraceCorruptError& e) {
      result.input_error = e;
      break;
    }
    if (!r) break;
    ++result.records_read;
    if (!start) start = r->time_ns;
    const std::uint64_t chunk = reader.current_chunk();
    if (connected.size() < reader.devices().size())
      connected.resize(reader.devices().size(), false);
    if (r->type == TraceRecordType::kDeviceAdded) {
      // Kept wherever it falls, so that the device indices of the kept records stay valid; one
      // before the window is written when the window opens.
      TraceDevice device = decode_device(r->payload, reader.name());
      if (window_open) {
        writer.add_device(r->time_ns, device);
        ++result.records_written;
      } else {
        pending_devices.push_back(std::move(device));
      }
      continue;
    }
    const bool after_from = (!options.from_s || r->time_ns >= *start + to_ns(*options.from_s)) &&
                            (!options.from_chunk || chunk >= *options.from_chunk);
    const bool before_to = (!options.to_s || r->time_ns <= *start + to_ns(*options.to_s)) &&
                           (!options.to_chunk || chunk <= *options.to_chunk);
    if (!after_from) {
      if (r->type == TraceRecordType::kConnect) connected[r->device] = true;
      if (r->type == TraceRecordType::kDisconnect) connected[r->device] = false;
      continue;
    }
    if (!before_to) break;
    if (!window_open) {
      window_open = true;
      for (const TraceDevice& device : pending_devices)
        writer.add_device(r->time_ns, device);
      result.records_written += pending_devices.size();
      pending_devices.clear();
      writer.note(r->time_ns, note);
      ++result.records_written;
      for (std::size_t d = 0; d < connected.size(); ++d) {
        if (connected[d]) {
          writer.connect(static_cast<std::uint16_t>(d), r->time_ns);
          ++result.records_written;
        }
      }
    }
    writer.append(r->type, r->device, r->time_ns, r->payload);
    ++result.records_written;
  }
  // Devices of a window that holds no record (so the cut names every device all the same).
  for (const TraceDevice& device : pending_devices) {
    writer.add_device(start.value_or(header.start_time_ns), device);
    ++result.records_written;
  }
  writer.close(/*session_ended=*/false);
  result.chunks_written = writer.stats().chunks;
  return result;
}

}  // namespace bisturi::devices
