// Replay of a recorded session in virtual time (see session_replay.h).

#include "bisturi/runtime/session/session_replay.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <memory>
#include <nlohmann/json.hpp>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/session_sim.h"
#include "lockstep_notes.h"
#include "step_schedule.h"
#include "tissue_thread.h"

namespace bisturi::runtime {

namespace {

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

}  // namespace

SessionReplayResult replay_session(const std::filesystem::path& trace) {
  const auto wall_start = std::chrono::steady_clock::now();
  SessionReplayResult result;
  {
    devices::TraceReader reader(trace);
    result.devices = devices::replay_trace(reader);
  }

  devices::TraceReader reader(trace);
  const nlohmann::json config = nlohmann::json::parse(reader.header().config, nullptr, false);
  if (config.is_discarded() || !config.is_object() || !config.contains("session"))
    throw devices::TraceError(reader.name() +
                              ": the trace's configuration holds no session (not written by "
                              "bisturi run --record)");
  std::string scene_toml, base_dir;
  std::uint16_t glove_index = 0;
  std::uint32_t lag = 0;             // traces without the key ran the tissue step inside the tick
  std::uint32_t ticks_per_step = 1;  // and traces without this one stepped at every tick
  std::uint32_t tissue_threads = 1;  // and on one thread
  try {
    const nlohmann::json& s = config.at("session");
    scene_toml = s.at("scene_toml").get<std::string>();
    base_dir = s.at("base_dir").get<std::string>();
    glove_index = s.at("glove_device").get<std::uint16_t>();
    if (s.contains("tissue_lag_ticks")) lag = s.at("tissue_lag_ticks").get<std::uint32_t>();
    if (s.contains("tissue_ticks_per_step"))
      ticks_per_step = std::max(1u, s.at("tissue_ticks_per_step").get<std::uint32_t>());
    if (s.contains("tissue_threads")) tissue_threads = s.at("tissue_threads").get<std::uint32_t>();
  } catch (const nlohmann::json::exception& e) {
    throw devices::TraceError(reader.name() + ": session configuration: " + e.what());
  }
  if (tissue_threads < 1 || tissue_threads > kMaxTissueThreads)
    throw devices::TraceError(reader.name() + ": session configuration: tissue_threads " +
                              std::to_string(tissue_threads) + " is not between 1 and " +
                              std::to_string(kMaxTissueThreads));
  result.tissue_threads = tissue_threads;
  const SceneDescription scene =
      parse_scene(scene_toml, reader.name() + " (recorded scene)", base_dir);
  result.scene = scene.name;
  std::vector<BuiltSolid> solids = build_solids(scene);

  devices::VirtualClock clock(devices::Nanoseconds{reader.header().start_time_ns});
  const devices::Registry registry = devices::builtin_registry();
  std::unique_ptr<devices::Device> device;
  devices::HapticDevice* glove = nullptr;
  std::shared_ptr<devices::ReplayLink> link;
  std::unique_ptr<SessionSim> sim;
  devices::HapticState state;
  bool lost = false;

  // The lockstep of the live session (step_schedule.h): a hand-over tick queues its glove state
  // as the next step, each tick uses the step due, or the one its late-tick note names, and the
  // ticks per step change where a rate note says; steps run when a tick needs them.
  StepSchedule schedule(lag, ticks_per_step);
  std::deque<std::pair<devices::HapticState, std::uint32_t>> queued;
  std::uint64_t steps_run = 0;
  const TickOutput* step_output = nullptr;
  std::optional<LateTick> late;
  std::optional<TissueRateChange> rate;
  std::vector<double> command;
  const auto run_steps_to = [&](std::uint64_t j) {
    while (steps_run < j && !queued.empty()) {
      step_output = &sim->tick(queued.front().first, queued.front().second);
      queued.pop_front();
      ++steps_run;
    }
  };
  const auto haptic_tick = [&] {  // returns the step the tick's command comes from
    ++result.ticks;
    const std::uint64_t k = result.ticks;
    if (schedule.hands_over(k)) {
      queued.emplace_back(state, schedule.handed_over_ticks());
      if (rate && rate->tick == k) schedule.set_ticks_per_step(k, rate->ticks_per_step);
    }
    rate.reset();
    std::uint64_t j = schedule.due(k);
    if (late && late->tick == k) j = std::min(late->step, schedule.steps());
    late.reset();
    run_steps_to(j);
    return j;
  };

  for (;;) {
    std::optional<devices::TraceRecord> r;
    try {
      r = reader.next();
    } catch (const devices::TraceCorruptError& e) {
      result.trace_error = e;
      break;
    }
    if (!r) break;
    clock.set(devices::Nanoseconds{r->time_ns});
    if (r->type == devices::TraceRecordType::kNote) {
      const std::string text(r->payload.begin(), r->payload.end());
      if (text == "tick" && sim) {
        (void)haptic_tick();
      } else if (auto l = parse_late_tick_note(text)) {
        late = l;
      } else if (auto c = parse_tissue_rate_note(text)) {
        rate = c;
      } else {
        const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
        if (!j.is_discarded() && j.is_object() && j.contains("session_end")) {
          const nlohmann::json& e = j["session_end"];
          if (e.contains("state_hash"))
            result.expected_state_hash = e["state_hash"].get<std::uint64_t>();
          if (e.contains("ticks")) result.expected_ticks = e["ticks"].get<std::uint64_t>();
        }
      }
      continue;
    }
    if (r->device != glove_index) continue;
    switch (r->type) {
      case devices::TraceRecordType::kConnect: {
        if (device) device->close();
        auto transport = std::make_unique<devices::ReplayTransport>(
            devices::to_device_descriptor(reader.devices().at(glove_index)), clock);
        link = transport->link();
        device = registry.open(std::move(transport), clock);
        glove = devices::as_haptic(device.get());
        if (glove == nullptr)
          throw devices::TraceError(reader.name() + ": the recorded glove is not a haptic device");
        if (!sim) {
          SessionSimOptions sim_options;
          sim_options.tissue_threads = tissue_threads;
          sim = std::make_unique<SessionSim>(scene, std::move(solids),
                                             glove->capabilities().force_channels, sim_options);
        }
        lost = false;
        break;
      }
      case devices::TraceRecordType::kReportIn:
        if (!link || lost) break;
        link->push_input(devices::Nanoseconds{r->time_ns}, r->payload);
        try {
          glove->poll(std::chrono::microseconds(0));
          state = glove->state();
        } catch (const devices::ProtocolError&) {
          state = glove->state();
        } catch (const devices::DeviceDisconnected&) {
          lost = true;
        }
        break;
      case devices::TraceRecordType::kForceCommand: {
        if (!sim) throw devices::TraceError(reader.name() + ": a force command before the glove");
        const std::uint64_t j = haptic_tick();
        if (j > 0 && step_output != nullptr) {
          sim->command_for(*step_output, SessionSim::tip_of(state), command);
        } else {
          command.assign(sim->command_size(), 0.0);
        }
        ++result.force_commands;
        const std::vector<double> expected = r->forces_N();
        if (!same_bits(expected, command)) {
          ++result.force_mismatches;
          if (!result.first_mismatch)
            result.first_mismatch = ForceMismatch{result.ticks, r->time_ns, expected, command};
        }
        break;
      }
      case devices::TraceRecordType::kDisconnect:
        if (link) link->disconnect();
        lost = true;
        break;
      default:
        break;
    }
  }
  if (device) device->close();
  if (sim) {
    run_steps_to(schedule.steps());  // the live session ran every queued step before its hash
    result.state_hash = sim->state_hash();
  }
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

}  // namespace bisturi::runtime
