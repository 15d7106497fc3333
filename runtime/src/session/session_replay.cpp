// Replay of a recorded session in virtual time (see session_replay.h).

#include "bisturi/runtime/session/session_replay.h"

#include <algorithm>
#include <chrono>
#include <cstring>
#include <deque>
#include <memory>
#include <nlohmann/json.hpp>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/registry.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/recording_transport.h"
#include "bisturi/devices/trace/replay_transport.h"
#include "bisturi/devices/trace/trace_reader.h"
#include "bisturi/runtime/session/device_frame.h"
#include "bisturi/runtime/session/scene_builder.h"
#include "bisturi/runtime/session/session_devices.h"
#include "bisturi/runtime/session/session_sim.h"
#include "haptic_loop.h"
#include "lockstep_notes.h"
#include "step_schedule.h"
#include "tissue_thread.h"

namespace bisturi::runtime {

namespace {

bool same_bits(const std::vector<double>& a, const std::vector<double>& b) {
  return a.size() == b.size() &&
         (a.empty() || std::memcmp(a.data(), b.data(), a.size() * sizeof(double)) == 0);
}

/// The tissue steps of a replay: run in place when a tick needs them, late where the trace's
/// late-tick note says, their length changed where a rate note says, the blood's clock held
/// where a blood-hold note says (each note applies to the tick that follows it).
class ReplayTickSteps final : public TickSteps {
 public:
  explicit ReplayTickSteps(SessionSim& sim) : sim_(sim) {}
  TissueThread::Push push(std::span<const devices::HapticState> states, std::uint32_t ticks,
                          bool blood_held) override {
    if (dropped) {  // the live tissue could not take this one (its note precedes the push)
      dropped.reset();
      return TissueThread::Push::Behind;
    }
    queued_.push_back(
        {std::vector<devices::HapticState>(states.begin(), states.end()), ticks, blood_held});
    ++pushed_;
    return TissueThread::Push::Queued;
  }
  TissueThread::TickStep step_for(std::uint64_t k, std::uint64_t due) override {
    TissueThread::TickStep use{due, nullptr, false};
    if (late && late->tick == k) use = {std::min(late->step, pushed_), nullptr, true};
    late.reset();
    rate.reset();
    run_to(use.step);
    if (use.step > 0) use.output = newest_;
    return use;
  }
  std::uint32_t ticks_per_step(std::uint64_t k, std::uint32_t n) override {
    return rate && rate->tick == k ? rate->ticks_per_step : n;
  }
  bool blood_held(std::uint64_t k, bool now) override {
    const bool held = hold && hold->tick == k ? hold->held : now;
    hold.reset();
    return held;
  }
  [[nodiscard]] std::uint64_t backlog() const override { return queued_.size(); }
  void run_all() { run_to(pushed_); }

  std::optional<LateTick> late;
  std::optional<TissueRateChange> rate;
  std::optional<DroppedStep> dropped;
  std::optional<BloodHold> hold;

 private:
  struct Queued {
    std::vector<devices::HapticState> states;
    std::uint32_t ticks = 1;
    bool blood_held = false;
  };
  void run_to(std::uint64_t j) {
    while (run_ < j && !queued_.empty()) {
      const Queued& q = queued_.front();
      newest_ = &sim_.tick(q.states, q.ticks, q.blood_held);
      queued_.pop_front();
      ++run_;
    }
  }

  SessionSim& sim_;
  std::deque<Queued> queued_;
  std::uint64_t pushed_ = 0;
  std::uint64_t run_ = 0;
  const TickOutput* newest_ = nullptr;
};

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
  const devices::Nanoseconds t0{reader.header().start_time_ns};
  const devices::Registry registry = devices::builtin_registry();
  const devices::ForceGuardConfig guard_config =
      devices::force_guard_config_from_json(reader.header().config);
  const DeviceChoice choice = choose_session_devices(scene);
  // One per hand: hand h's device is device glove_index + h of the trace (opened in order).
  struct ReplayHand {
    std::uint16_t index = 0;
    std::unique_ptr<devices::Device> device;
    devices::HapticDevice* haptic = nullptr;
    std::shared_ptr<devices::ReplayLink> link;
    std::unique_ptr<devices::ForceGuard> guard;
    std::unique_ptr<devices::GuardedHaptic> guarded;
    bool open_pending = false;
    /// A "haptic_stop" or "watchdog_zero" note for this hand: its next force command is that
    /// zero, not a tick.
    enum class Zero : std::uint8_t { None, Stop, Watchdog } pending_zero = Zero::None;
    std::vector<double> zeros;
  };
  std::vector<ReplayHand> hands(choice.hands.size());
  for (std::size_t h = 0; h < hands.size(); ++h)
    hands[h].index = static_cast<std::uint16_t>(glove_index + h);
  const auto hand_of = [&](std::uint16_t device) -> ReplayHand* {
    for (ReplayHand& h : hands)
      if (h.index == device) return &h;
    return nullptr;
  };
  std::unique_ptr<SessionSim> sim;
  std::unique_ptr<ReplayTickSteps> steps;
  std::unique_ptr<HapticLoop> loop;

  // Builds the simulation and the loop once every hand's driver is open.
  const auto start_loop = [&] {
    std::vector<HandSetup> setups;
    for (std::size_t h = 0; h < hands.size(); ++h) {
      const devices::HapticDevice& d = *hands[h].haptic;
      HandSetup setup{d.capabilities().force_channels,
                      device_frame_of(*choice.hands[h]),
                      d.capabilities().spec,
                      {},
                      {},
                      choice.hands[h]->max_force_N};
      if (const devices::DriverInfo* driver = registry.find_by_name(d.driver_name())) {
        setup.channel_roles = driver->layout.roles(d.capabilities());
        setup.button_uses = driver->layout.button_uses(d.capabilities());
      }
      setups.push_back(std::move(setup));
    }
    SessionSimOptions sim_options;
    sim_options.tissue_threads = tissue_threads;
    sim = std::make_unique<SessionSim>(scene, std::move(solids), setups, sim_options);
    steps = std::make_unique<ReplayTickSteps>(*sim);
    HapticLoopParts parts;
    parts.stale_margin_ticks = static_cast<std::uint32_t>(scene.simulation.stale_margin_ticks);
    for (std::size_t h = 0; h < hands.size(); ++h) {
      ReplayHand& hand = hands[h];
      hand.guard = std::make_unique<devices::ForceGuard>(sim->guard_channels(h), guard_config);
      hand.guarded = std::make_unique<devices::GuardedHaptic>(*hand.haptic, *hand.guard, clock);
      hand.zeros.assign(sim->command_size(h), 0.0);
      parts.hands.push_back(
          {hand.guarded.get(), setups[h].device_frame,
           devices::buttons_with(setups[h].button_uses, devices::ButtonUse::Clutch)});
    }
    parts.steps = steps.get();
    parts.sim = sim.get();
    parts.clock = &clock;
    loop = std::make_unique<HapticLoop>(std::move(parts), lag, ticks_per_step);
  };
  // Opens a hand's driver (false while it waits for the recording's first report:
  // devices::open_replayed), and the loop once every hand's is open.
  const auto open_hand = [&](ReplayHand& hand) -> bool {
    hand.device = devices::open_replayed(
        registry, devices::to_device_descriptor(reader.devices().at(hand.index)), clock, hand.link);
    if (!hand.device) return false;
    hand.haptic = devices::as_haptic(hand.device.get());
    if (hand.haptic == nullptr)
      throw devices::TraceError(reader.name() + ": recorded device " + std::to_string(hand.index) +
                                " is not a haptic device");
    const bool all_open = std::all_of(hands.begin(), hands.end(),
                                      [](const ReplayHand& h) { return h.haptic != nullptr; });
    if (all_open) start_loop();
    return true;
  };
  const auto compare = [&](const std::vector<double>& expected, const std::vector<double>& actual,
                           std::int64_t time_ns) {
    ++result.force_commands;
    if (!same_bits(expected, actual)) {
      ++result.force_mismatches;
      if (!result.first_mismatch)
        result.first_mismatch = ForceMismatch{result.ticks, time_ns, expected, actual};
    }
  };
  const auto tick = [&] {
    (void)loop->tick(clock.now() - t0);
    result.ticks = loop->counters().ticks;
    for (ReplayHand& h : hands) {
      if (h.link) (void)h.link->take_written();  // devices::replay_trace checks the bytes
    }
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
      if (text == "tick" && loop) {
        tick();
      } else if (const auto stop = parse_hand_note(text, "haptic_stop")) {
        if (*stop < hands.size()) hands[*stop].pending_zero = ReplayHand::Zero::Stop;
      } else if (const auto zero = parse_hand_note(text, "watchdog_zero")) {
        if (*zero < hands.size()) hands[*zero].pending_zero = ReplayHand::Zero::Watchdog;
      } else if (text == "display_hold" || text == "display_live") {
        if (loop) loop->hold_display(text == "display_hold");
      } else if (auto l = parse_late_tick_note(text)) {
        if (steps) steps->late = l;
      } else if (auto c = parse_tissue_rate_note(text)) {
        if (steps) steps->rate = c;
      } else if (auto d = parse_dropped_step_note(text)) {
        if (steps) steps->dropped = d;
      } else if (auto b = parse_blood_hold_note(text)) {
        if (steps) steps->hold = b;
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
    ReplayHand* hand = hand_of(r->device);
    if (hand == nullptr) continue;
    const std::size_t h = static_cast<std::size_t>(hand - hands.data());
    switch (r->type) {
      case devices::TraceRecordType::kConnect: {
        if (hand->device || hand->open_pending)
          throw devices::TraceError(reader.name() + ": haptic device " +
                                    std::to_string(hand->index) +
                                    " connects twice; a session never reopens it");
        hand->open_pending = !open_hand(*hand);
        break;
      }
      case devices::TraceRecordType::kReportIn:
        if (!hand->link || (loop && loop->device_lost(h))) break;
        hand->link->push_input(devices::Nanoseconds{r->time_ns}, r->payload);
        if (hand->open_pending) {
          hand->open_pending = !open_hand(*hand);
          break;
        }
        if (!hand->guarded) break;
        // Read at its own time, as the live driver did (its sample time feeds the guard).
        try {
          hand->guarded->poll(std::chrono::microseconds(0));
        } catch (const devices::ProtocolError&) {
        } catch (const devices::DeviceDisconnected&) {
        }
        break;
      case devices::TraceRecordType::kForceCommand: {
        if (!loop)
          throw devices::TraceError(reader.name() + ": a force command before every hand's device");
        const std::vector<double> expected = r->forces_N();
        if (hand->pending_zero == ReplayHand::Zero::Stop) {
          loop->stop();  // every hand's zero (the live stop sent them one after another)
          compare(expected, hand->zeros, r->time_ns);
        } else if (hand->pending_zero == ReplayHand::Zero::Watchdog) {
          loop->zero_now(h);
          compare(expected, hand->zeros, r->time_ns);
        } else {
          if (h == 0) tick();  // the first hand's command is the tick's first
          compare(expected, loop->command(h), r->time_ns);
        }
        hand->pending_zero = ReplayHand::Zero::None;
        break;
      }
      case devices::TraceRecordType::kDisconnect:
        if (hand->link) hand->link->disconnect();
        break;
      default:
        break;
    }
  }
  for (ReplayHand& hand : hands) {
    if (hand.device) hand.device->close();
  }
  if (sim) {
    steps->run_all();  // the live session ran every queued step before its hash
    result.state_hash = sim->state_hash();
  }
  result.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - wall_start).count();
  return result;
}

}  // namespace bisturi::runtime
