// `bisturi trace forces`: what a recorded session's force commands did to the hand, channel by
// channel: the largest force, how often it sat at the limit, the largest change from one tick to
// the next against the device's rate limit, and how much it chattered. Fault zeros (a
// "haptic_stop", "watchdog_zero" or "display_hold" note before the command: the session ending,
// a stalled tick, a picture the trainee no longer sees) may drop at once and are counted apart.
#include <algorithm>
#include <cmath>
#include <deque>
#include <iostream>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "trace_command.h"
#include "trace_devices.h"

namespace bisturi::cli {

namespace {

using nlohmann::json;

constexpr int kExitBadChunk = 2;
constexpr double kReversal_N = 0.02;        // a change smaller than this is not a reversal
constexpr std::size_t kChatterWindow = 11;  // ticks of the moving mean chatter is measured from

struct ChannelStats {
  devices::ForceChannel channel;
  std::size_t offset = 0;
  double limit_N = 0.0;
  double allowed_step_N = 0.0;
  std::uint64_t commands = 0;
  double max_N = 0.0;
  std::uint64_t at_limit = 0;
  double largest_step_N = 0.0;
  double largest_step_time_s = 0.0;
  std::uint64_t steps_above_rate = 0;
  std::uint64_t reversals = 0;
  double chatter_sum_sq = 0.0;
  std::uint64_t chatter_samples = 0;
  double chatter_max_N = 0.0;
  double impulse_N_s = 0.0;  // the magnitude's integral over time: what the hand took in all
  // State between commands.
  std::vector<double> last;
  double last_time_s = -1.0;
  double last_magnitude_N = 0.0;
  double last_change = 0.0;   // signed change of the magnitude at the last command
  std::deque<double> window;  // recent magnitudes, for the chatter's moving mean
};

double magnitude(const std::vector<double>& f, std::size_t offset, std::size_t n) {
  double sum = 0.0;
  for (std::size_t i = 0; i < n; ++i)
    sum += f[offset + i] * f[offset + i];
  return std::sqrt(sum);
}

void add_command(ChannelStats& s, const std::vector<double>& forces, double time_s,
                 bool fault_zero) {
  const std::size_t n = s.channel.components;
  const double m = magnitude(forces, s.offset, n);
  ++s.commands;
  s.max_N = std::max(s.max_N, m);
  // Each command holds until the next one.
  if (s.last_time_s >= 0.0) s.impulse_N_s += s.last_magnitude_N * (time_s - s.last_time_s);
  s.last_time_s = time_s;
  s.last_magnitude_N = m;
  if (m >= s.limit_N * (1.0 - 1e-9)) ++s.at_limit;
  std::vector<double> now(forces.begin() + static_cast<std::ptrdiff_t>(s.offset),
                          forces.begin() + static_cast<std::ptrdiff_t>(s.offset + n));
  if (!s.last.empty() && !fault_zero) {
    double sq = 0.0;
    for (std::size_t i = 0; i < n; ++i)
      sq += (now[i] - s.last[i]) * (now[i] - s.last[i]);
    const double step = std::sqrt(sq);
    if (step > s.largest_step_N) {
      s.largest_step_N = step;
      s.largest_step_time_s = time_s;
    }
    if (step > s.allowed_step_N * (1.0 + 1e-9) + 1e-12) ++s.steps_above_rate;
    const double change = m - magnitude(s.last, 0, n);
    if (std::abs(change) > kReversal_N && std::abs(s.last_change) > kReversal_N &&
        (change > 0) != (s.last_change > 0))
      ++s.reversals;
    s.last_change = change;
  }
  // A fault's zero is the safety path's, not the loop's: the loop's next command follows its
  // own last one (the guard holds the device at zero meanwhile), so steps are measured from it.
  if (!fault_zero || s.last.empty()) s.last = std::move(now);
  s.window.push_back(m);
  if (s.window.size() > kChatterWindow) s.window.pop_front();
  if (s.window.size() == kChatterWindow) {
    double mean = 0.0;
    for (double v : s.window)
      mean += v;
    mean /= static_cast<double>(kChatterWindow);
    const double centre = s.window[kChatterWindow / 2] - mean;
    s.chatter_sum_sq += centre * centre;
    ++s.chatter_samples;
    s.chatter_max_N = std::max(s.chatter_max_N, std::abs(centre));
  }
}

json channel_json(const ChannelStats& s) {
  return {
      {"channel", s.channel.name},
      {"components", s.channel.components},
      {"limit_N", s.limit_N},
      {"rate_limit_N_per_s", s.channel.max_force_rate_N_per_s},
      {"allowed_step_N", s.allowed_step_N},
      {"commands", s.commands},
      {"max_N", s.max_N},
      {"impulse_N_s", s.impulse_N_s},
      {"at_limit", s.at_limit},
      {"largest_step_N", s.largest_step_N},
      {"largest_step_time_s", s.largest_step_time_s},
      {"steps_above_rate", s.steps_above_rate},
      {"reversals", s.reversals},
      {"chatter_rms_N", s.chatter_samples > 0
                            ? std::sqrt(s.chatter_sum_sq / static_cast<double>(s.chatter_samples))
                            : 0.0},
      {"chatter_max_N", s.chatter_max_N}};
}

}  // namespace

int run_trace_forces(const TraceOptions& options) {
  const devices::Registry registry = devices::builtin_registry();
  std::vector<std::unique_ptr<DecodedDevice>> decoded =
      decode_trace_devices(options.input, registry);
  devices::TraceReader reader(options.input);
  const devices::ForceGuardConfig guard =
      devices::force_guard_config_from_json(reader.header().config);
  const double period_s = std::chrono::duration<double>(guard.period).count();

  std::vector<std::vector<ChannelStats>> stats(decoded.size());
  std::vector<std::uint64_t> fault_zeros(decoded.size(), 0);
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    const auto* haptic =
        decoded[i]->driver ? devices::as_haptic(decoded[i]->driver.get()) : nullptr;
    if (haptic == nullptr) continue;
    std::size_t offset = 0;
    for (const devices::ForceChannel& c : haptic->capabilities().force_channels) {
      ChannelStats s;
      s.channel = c;
      s.offset = offset;
      s.limit_N = options.limit_N ? std::min(*options.limit_N, c.max_force_N) : c.max_force_N;
      s.allowed_step_N = c.max_force_rate_N_per_s * period_s;
      offset += c.components;
      stats[i].push_back(std::move(s));
    }
  }
  const std::int64_t start = reader.header().start_time_ns;
  std::vector<bool> zero_pending(decoded.size(), false);
  std::optional<devices::TraceCorruptError> bad;
  try {
    while (auto r = reader.next()) {
      if (r->device >= decoded.size()) continue;
      if (r->type == devices::TraceRecordType::kNote) {
        const std::string text(r->payload.begin(), r->payload.end());
        if (text == "haptic_stop" || text == "watchdog_zero" || text == "display_hold")
          zero_pending[r->device] = true;
        continue;
      }
      if (r->type != devices::TraceRecordType::kForceCommand) continue;
      const std::vector<double> forces = r->forces_N();
      const bool fault_zero = zero_pending[r->device];
      zero_pending[r->device] = false;
      if (fault_zero) ++fault_zeros[r->device];
      const double t = static_cast<double>(r->time_ns - start) * 1e-9;
      for (ChannelStats& s : stats[r->device]) {
        if (s.offset + s.channel.components <= forces.size()) add_command(s, forces, t, fault_zero);
      }
    }
  } catch (const devices::TraceCorruptError& e) {
    bad = e;
  }

  json devices_out = json::array();
  for (std::size_t i = 0; i < decoded.size(); ++i) {
    if (stats[i].empty()) continue;
    json channels = json::array();
    for (const ChannelStats& s : stats[i])
      channels.push_back(channel_json(s));
    devices_out.push_back({{"index", i},
                           {"driver", decoded[i]->trace.driver},
                           {"fault_zeros", fault_zeros[i]},
                           {"channels", channels}});
  }
  const json out = {{"file", options.input},
                    {"period_ms", period_s * 1e3},
                    {"devices", devices_out},
                    {"trace_error", bad ? json(bad->what()) : json(nullptr)}};
  if (options.json) {
    std::cout << out.dump(2) << "\n";
  } else {
    for (const json& d : devices_out) {
      std::cout << "device " << d["index"] << " (" << d["driver"].get<std::string>()
                << "), fault zeros " << d["fault_zeros"] << "\n";
      for (const json& c : d["channels"]) {
        std::cout << "  " << c["channel"].get<std::string>() << ": max " << c["max_N"]
                  << " N, impulse " << c["impulse_N_s"] << " N (limit " << c["limit_N"] << ", "
                  << c["at_limit"] << " at it); largest step " << c["largest_step_N"] << " N at "
                  << c["largest_step_time_s"] << " s (rate allows " << c["allowed_step_N"] << ", "
                  << c["steps_above_rate"] << " above); " << c["reversals"]
                  << " reversals, chatter rms " << c["chatter_rms_N"] << " N\n";
      }
    }
    if (bad) std::cout << "bad chunk: " << bad->what() << "\n";
  }
  return bad ? kExitBadChunk : 0;
}

}  // namespace bisturi::cli
