#include "hid_mapping.h"

#include <algorithm>
#include <cmath>

namespace bisturi::devices::detail {

namespace {

using hid::Field;
using hid::Unit;

InputReportMap& input_map(std::vector<InputReportMap>& maps, std::uint8_t id) {
  for (auto& map : maps) {
    if (map.id == id) return map;
  }
  maps.push_back(InputReportMap{});
  maps.back().id = id;
  return maps.back();
}

int bind(InputReportMap& map, std::uint32_t field, std::uint32_t element) {
  map.bindings.push_back(Binding{field, element});
  return static_cast<int>(map.bindings.size() - 1);
}

Quaternion multiply(const Quaternion& a, const Quaternion& b) {
  return {
      a.w * b.w - a.x * b.x - a.y * b.y - a.z * b.z, a.w * b.x + a.x * b.w + a.y * b.z - a.z * b.y,
      a.w * b.y - a.x * b.z + a.y * b.w + a.z * b.x, a.w * b.z + a.x * b.y - a.y * b.x + a.z * b.w};
}

bool is_force_output(std::uint32_t usage) {
  return usage == hid::kUsagePidMagnitude || usage == hid::kUsageHapticIntensity;
}

}  // namespace

HidMapping::HidMapping(const DeviceDescriptor& device, double max_force_rate_N_per_s)
    : codec_(hid::parse_report_descriptor(device.report_descriptor, describe(device)),
             describe(device)) {
  const auto& descriptor = codec_.descriptor();
  application_ = descriptor.application_usage();
  std::uint32_t button_count = 0;
  std::size_t joint_count = 0;
  bool has_axis[3] = {false, false, false};
  for (std::uint32_t f = 0; f < descriptor.fields.size(); ++f) {
    const Field& field = descriptor.fields[f];
    const auto quantity = field.unit.quantity();
    if (field.type == hid::ReportType::Input) {
      InputReportMap& map = input_map(inputs_, field.report_id);
      if (!field.is_variable()) {
        if (!field.usages.empty() && (field.usages.front() >> 16) == hid::kPageButton) {
          map.button_arrays.push_back(f);
          for (auto u : field.usages) {
            const std::uint32_t id = u & 0xFFFF;
            if ((u >> 16) == hid::kPageButton && id >= 1 && id <= 64) {
              button_count = std::max(button_count, id);
            }
          }
        }
        continue;
      }
      for (std::uint32_t e = 0; e < field.count; ++e) {
        const std::uint32_t u = field.usage_of(e);
        if ((u == hid::kUsageX || u == hid::kUsageY || u == hid::kUsageZ) &&
            quantity == Unit::Quantity::Length) {
          const auto axis = u - hid::kUsageX;
          if (map.position[axis] < 0) map.position[axis] = bind(map, f, e);
          if (!has_axis[axis]) {
            // The box the device can report positions in: the workspace it states.
            const double a = field.to_si(field.logical_min), b = field.to_si(field.logical_max);
            double* lo[3] = {&capabilities_.spec.workspace_min_m.x,
                             &capabilities_.spec.workspace_min_m.y,
                             &capabilities_.spec.workspace_min_m.z};
            double* hi[3] = {&capabilities_.spec.workspace_max_m.x,
                             &capabilities_.spec.workspace_max_m.y,
                             &capabilities_.spec.workspace_max_m.z};
            *lo[axis] = std::min(a, b);
            *hi[axis] = std::max(a, b);
            has_axis[axis] = true;
          }
          has_position_ = true;
        } else if (u == hid::kUsageOrientationQuaternion && e < 4) {
          if (map.quaternion[e] < 0) map.quaternion[e] = bind(map, f, e);
        } else if ((u == hid::kUsageRx || u == hid::kUsageRy || u == hid::kUsageRz) &&
                   quantity == Unit::Quantity::Rotation) {
          const auto axis = u - hid::kUsageRx;
          if (map.euler[axis] < 0) map.euler[axis] = bind(map, f, e);
        } else if (u == hid::kUsageFlexor && quantity == Unit::Quantity::Rotation) {
          map.bindings.push_back(Binding{f, e});
          map.joints.emplace_back(joint_count++, map.bindings.back());
        } else if ((u >> 16) == hid::kPageButton) {
          const std::uint32_t id = u & 0xFFFF;
          if (id >= 1 && id <= 64) {
            map.buttons.emplace_back(id - 1, Binding{f, e});
            button_count = std::max(button_count, id);
          }
        }
      }
    } else if (field.type == hid::ReportType::Output && field.is_variable()) {
      for (std::uint32_t e = 0; e < field.count; ++e) {
        const std::uint32_t u = field.usage_of(e);
        auto output = std::find_if(outputs_.begin(), outputs_.end(), [&](const ForceOutput& o) {
          return o.report_id == field.report_id;
        });
        if (u == hid::kUsagePidEffectBlockIndex) {
          if (output == outputs_.end()) {
            outputs_.push_back(ForceOutput{field.report_id, {}, {}});
            output = outputs_.end() - 1;
          }
          output->effect_block_index.push_back(Binding{f, e});
          continue;
        }
        if (!is_force_output(u)) continue;
        if (output == outputs_.end()) {
          outputs_.push_back(ForceOutput{field.report_id, {}, {}});
          output = outputs_.end() - 1;
        }
        ForceChannel channel;
        channel.name = "actuator_" + std::to_string(capabilities_.force_channels.size());
        channel.components = 1;
        channel.max_force_rate_N_per_s = max_force_rate_N_per_s;
        if (quantity == Unit::Quantity::Force) {
          channel.max_force_N = std::max(std::abs(field.to_si(field.logical_max)),
                                         std::abs(field.to_si(field.logical_min)));
        } else {
          channel.max_force_N = 1.0;
          channel.unitless = true;
        }
        output->channels.emplace_back(capabilities_.force_channels.size(), Binding{f, e});
        capabilities_.force_channels.push_back(std::move(channel));
      }
    }
  }
  // Reports that carry only an effect block index are not force outputs.
  std::erase_if(outputs_, [](const ForceOutput& o) { return o.channels.empty(); });
  std::erase_if(inputs_, [](const InputReportMap& m) {
    return m.bindings.empty() && m.button_arrays.empty();
  });
  for (const auto& map : inputs_) {
    if (std::all_of(std::begin(map.quaternion), std::end(map.quaternion),
                    [](int b) { return b >= 0; }) ||
        std::any_of(std::begin(map.euler), std::end(map.euler), [](int b) { return b >= 0; })) {
      has_orientation_ = true;
    }
  }
  capabilities_.end_effectors = has_pose() ? 1 : 0;
  capabilities_.buttons = button_count;
  for (std::size_t j = 0; j < joint_count; ++j) {
    capabilities_.finger_joints.push_back("joint_" + std::to_string(j));
  }
  if (application_ == hid::kUsageHeadTracker || application_ == hid::kUsageHeadMountedDisplay) {
    capabilities_.device_class = DeviceClass::HeadTracker;
    capabilities_.head_pose = true;
  } else {
    capabilities_.device_class = DeviceClass::HapticGlove;
  }
}

bool HidMapping::apply(std::span<const std::uint8_t> report, Pose* pose,
                       std::vector<double>* joints_rad, std::uint64_t* buttons) const {
  const hid::ReportInfo& info = codec_.check(hid::ReportType::Input, report);
  const InputReportMap* map = nullptr;
  for (const auto& candidate : inputs_) {
    if (candidate.id == info.id) map = &candidate;
  }
  if (!map) return false;
  const auto& fields = codec_.descriptor().fields;
  auto value = [&](int binding) {
    const Binding& b = map->bindings[static_cast<std::size_t>(binding)];
    return codec_.si(report, fields[b.field], b.element);
  };
  if (pose) {
    double* position[3] = {&pose->position_m.x, &pose->position_m.y, &pose->position_m.z};
    for (int axis = 0; axis < 3; ++axis) {
      if (map->position[axis] >= 0) *position[axis] = value(map->position[axis]);
    }
    if (map->quaternion[0] >= 0 && map->quaternion[1] >= 0 && map->quaternion[2] >= 0 &&
        map->quaternion[3] >= 0) {
      Quaternion q{value(map->quaternion[3]), value(map->quaternion[0]), value(map->quaternion[1]),
                   value(map->quaternion[2])};
      const double n = std::sqrt(q.w * q.w + q.x * q.x + q.y * q.y + q.z * q.z);
      if (!(n > 1e-6) || !std::isfinite(n)) {
        const auto& b = map->bindings[static_cast<std::size_t>(map->quaternion[0])];
        throw ProtocolError(codec_.device(),
                            (fields[b.field].bit_offset + (info.with_id ? 8u : 0u)) / 8,
                            "orientation quaternion of zero length");
      }
      pose->orientation = {q.w / n, q.x / n, q.y / n, q.z / n};
    } else if (map->euler[0] >= 0 || map->euler[1] >= 0 || map->euler[2] >= 0) {
      // Rx, then Ry, then Rz about the fixed axes: q = qz * qy * qx.
      Quaternion q;
      for (int axis = 0; axis < 3; ++axis) {
        if (map->euler[axis] < 0) continue;
        const double half = value(map->euler[axis]) / 2;
        Quaternion r{std::cos(half), 0, 0, 0};
        (axis == 0 ? r.x : axis == 1 ? r.y : r.z) = std::sin(half);
        q = multiply(r, q);
      }
      pose->orientation = q;
    }
  }
  if (joints_rad) {
    for (const auto& [index, b] : map->joints) {
      if (index < joints_rad->size()) {
        (*joints_rad)[index] = codec_.si(report, fields[b.field], b.element);
      }
    }
  }
  if (buttons) {
    for (const auto& [bit, b] : map->buttons) {
      const std::uint64_t mask = std::uint64_t{1} << bit;
      if (codec_.logical(report, fields[b.field], b.element) != 0) {
        *buttons |= mask;
      } else {
        *buttons &= ~mask;
      }
    }
    for (std::uint32_t f : map->button_arrays) {
      const auto& field = fields[f];
      for (auto u : field.usages) {
        const std::uint32_t id = u & 0xFFFF;
        if ((u >> 16) == hid::kPageButton && id >= 1 && id <= 64) {
          *buttons &= ~(std::uint64_t{1} << (id - 1));
        }
      }
      for (std::uint32_t e = 0; e < field.count; ++e) {
        const std::int64_t index =
            std::int64_t{codec_.logical(report, field, e)} - field.logical_min;
        if (index < 0 || static_cast<std::uint64_t>(index) >= field.usages.size()) continue;
        const std::uint32_t u = field.usages[static_cast<std::size_t>(index)];
        const std::uint32_t id = u & 0xFFFF;
        if ((u >> 16) == hid::kPageButton && id >= 1 && id <= 64) {
          *buttons |= std::uint64_t{1} << (id - 1);
        }
      }
    }
  }
  return true;
}

void HidMapping::encode_forces(std::span<const double> forces_N,
                               std::vector<Bytes>& reports) const {
  reports.resize(outputs_.size());
  const auto& fields = codec_.descriptor().fields;
  for (std::size_t r = 0; r < outputs_.size(); ++r) {
    const ForceOutput& output = outputs_[r];
    Bytes& report = reports[r];
    report = codec_.make_report(hid::ReportType::Output, output.report_id);
    for (const auto& b : output.effect_block_index) {
      codec_.set_logical(report, fields[b.field], b.element, 1);
    }
    for (const auto& [channel, b] : output.channels) {
      const Field& field = fields[b.field];
      const double value = forces_N[channel];
      if (capabilities_.force_channels[channel].unitless) {
        const double fraction = std::clamp(std::isfinite(value) ? value : 0.0, 0.0, 1.0);
        const double logical =
            field.logical_min +
            fraction * (static_cast<double>(field.logical_max) - field.logical_min);
        codec_.set_logical(report, field, b.element,
                           static_cast<std::int32_t>(std::lround(logical)));
      } else {
        codec_.set_si(report, field, b.element, value);
      }
    }
  }
}

}  // namespace bisturi::devices::detail
