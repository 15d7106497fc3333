// `bisturi trace dump`: every record of a trace, decoded. Reports are decoded by the recorded
// device's own driver (rebuilt from the trace, as replay does) and, for HID devices, field by
// field through the report descriptor; force commands are grouped by the driver's channels.
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <nlohmann/json.hpp>
#include <string>

#include "bisturi/devices/hid_report.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "hex_bytes.h"
#include "hid_names.h"
#include "trace_devices.h"
#include "trace_command.h"

namespace bisturi::cli {

namespace {

namespace hid = devices::hid;
using nlohmann::json;

constexpr int kExitBadChunk = 2;

json vec3(const devices::Vec3& v) {
  return json::array({v.x, v.y, v.z});
}

json pose_json(const devices::Pose& p) {
  return {{"position_m", vec3(p.position_m)},
          {"orientation_wxyz",
           json::array({p.orientation.w, p.orientation.x, p.orientation.y, p.orientation.z})}};
}

json hid_fields(const DecodedDevice& d, hid::ReportType type,
                const std::vector<std::uint8_t>& bytes) {
  json fields = json::array();
  if (!d.codec) return fields;
  try {
    for (const hid::FieldValue& v : d.codec->decode(type, bytes))
      fields.push_back({{"usage", usage_name(v.usage)}, {"logical", v.logical}, {"si", v.si}});
  } catch (const devices::ProtocolError& e) {
    fields.push_back({{"error", e.what()}});
  }
  return fields;
}

json state_json(const devices::Device& device) {
  if (const auto* tracker = devices::as_tracker(const_cast<devices::Device*>(&device)))
    return {{"head_pose", pose_json(tracker->state().head_pose)}};
  const auto* haptic = devices::as_haptic(const_cast<devices::Device*>(&device));
  if (!haptic) return nullptr;
  json poses = json::array();
  for (const devices::Pose& p : haptic->state().end_effector_poses)
    poses.push_back(pose_json(p));
  return {{"end_effector_poses", poses},
          {"buttons", haptic->state().buttons},
          {"finger_joint_angles_rad", haptic->state().finger_joint_angles_rad}};
}

json forces_json(const DecodedDevice& d, const std::vector<double>& forces) {
  json out = json::array();
  const devices::HapticDevice* haptic = d.driver ? devices::as_haptic(d.driver.get()) : nullptr;
  if (!haptic || haptic->capabilities().force_components() != forces.size()) {
    for (double f : forces)
      out.push_back({{"channel", nullptr}, {"N", f}});
    return out;
  }
  std::size_t k = 0;
  for (const devices::ForceChannel& c : haptic->capabilities().force_channels) {
    if (c.components == 1) {
      out.push_back({{"channel", c.name}, {"N", forces[k++]}});
    } else {
      json v = json::array();
      for (std::size_t i = 0; i < c.components; ++i)
        v.push_back(forces[k++]);
      out.push_back({{"channel", c.name}, {"N", v}});
    }
  }
  return out;
}

std::string text_of(const json& record) {
  std::string line = std::to_string(record["time_s"].get<double>()) + " s  device " +
                     std::to_string(record["device"].get<int>()) + "  " +
                     record["type"].get<std::string>();
  if (record.contains("bytes")) line += "  [" + record["bytes"].get<std::string>() + "]";
  if (record.contains("forces")) {
    line += " ";
    for (const auto& f : record["forces"]) {
      line += " " + (f["channel"].is_null() ? std::string("?") : f["channel"].get<std::string>()) +
              "=" + f["N"].dump() + " N";
    }
  }
  if (record.contains("fields")) {
    for (const auto& f : record["fields"]) {
      if (f.contains("error")) {
        line += "\n      malformed: " + f["error"].get<std::string>();
        continue;
      }
      line += "\n      " + f["usage"].get<std::string>() + " = " + f["si"].dump();
    }
  }
  if (record.contains("state") && !record["state"].is_null())
    line += "\n      state " + record["state"].dump();
  if (record.contains("error")) line += "\n      malformed: " + record["error"].get<std::string>();
  if (record.contains("text")) line += "  " + record["text"].get<std::string>();
  return line;
}

}  // namespace

int run_trace_dump(const TraceOptions& options) {
  const devices::Registry registry = devices::builtin_registry();
  std::vector<std::unique_ptr<DecodedDevice>> decoded = decode_trace_devices(options.input, registry);
  const auto wanted = [&](std::uint16_t index) {
    if (options.device.empty()) return true;
    if (index >= decoded.size()) return false;
    const devices::TraceDevice& t = decoded[index]->trace;
    return options.device == std::to_string(index) || options.device == t.driver ||
           options.device == t.serial || options.device == t.product;
  };
  if (!options.device.empty()) {
    bool any = false;
    for (std::uint16_t i = 0; i < decoded.size(); ++i)
      any = any || wanted(i);
    if (!any)
      throw std::runtime_error(options.input + ": no device '" + options.device +
                               "' (give its index, driver, serial or product)");
  }

  devices::TraceReader reader(options.input);
  const std::int64_t start = reader.header().start_time_ns;
  json records = json::array();
  std::optional<devices::TraceCorruptError> bad;
  const auto emit = [&](const json& record) {
    if (options.json) {
      records.push_back(record);
    } else {
      std::cout << text_of(record) << "\n";
    }
  };
  try {
    while (auto r = reader.next()) {
      if (!wanted(r->device)) continue;
      json record = {{"time_s", static_cast<double>(r->time_ns - start) * 1e-9},
                     {"device", r->device},
                     {"type", devices::to_string(r->type)}};
      DecodedDevice* d = r->device < decoded.size() ? decoded[r->device].get() : nullptr;
      switch (r->type) {
        case devices::TraceRecordType::kReportIn:
        case devices::TraceRecordType::kReportOut: {
          const bool in = r->type == devices::TraceRecordType::kReportIn;
          record["direction"] = in ? "device to host" : "host to device";
          record["bytes"] = hex_bytes(r->payload);
          if (d && d->codec)
            record["fields"] =
                hid_fields(*d, in ? hid::ReportType::Input : hid::ReportType::Output, r->payload);
          if (in && d && d->driver) {
            try {
              d->clock.set(devices::Nanoseconds(r->time_ns));
              d->driver->handle_report(r->payload);
              record["state"] = state_json(*d->driver);
            } catch (const devices::ProtocolError& e) {
              record["error"] = e.what();
            }
          }
          break;
        }
        case devices::TraceRecordType::kForceCommand:
          record["forces"] = d ? forces_json(*d, r->forces_N()) : json::array();
          break;
        case devices::TraceRecordType::kNote:
          record["text"] = std::string(r->payload.begin(), r->payload.end());
          break;
        case devices::TraceRecordType::kDeviceAdded:
          record["text"] = "device added";
          break;
        default:
          break;
      }
      emit(record);
    }
  } catch (const devices::TraceCorruptError& e) {
    bad = e;
  }
  if (options.json) {
    json devices_out = json::array();
    for (std::size_t i = 0; i < decoded.size(); ++i) {
      const DecodedDevice& d = *decoded[i];
      devices_out.push_back(
          {{"index", i},
           {"product", d.trace.product},
           {"serial", d.trace.serial},
           {"driver", d.trace.driver},
           {"decoded_by_driver", d.driver != nullptr},
           {"driver_error", d.driver_error.empty() ? json(nullptr) : json(d.driver_error)}});
    }
    std::cout << json{{"file", options.input},
                      {"devices", devices_out},
                      {"records", records},
                      {"trace_error", bad ? json(bad->what()) : json(nullptr)}}
                     .dump(2)
              << "\n";
  } else if (bad) {
    std::cout << "bad chunk: " << bad->what() << "\n";
  }
  return bad ? kExitBadChunk : 0;
}

}  // namespace bisturi::cli
