#pragma once
// One haptic tick, the same code for the live session and its replay (session_replay.cpp):
//   the twins send (live) -> each hand's haptic device is polled (through its force guard) and
//   the head tracker too -> each device's state goes into the scene frame (DeviceFrame) -> on a
//   hand-over tick the hands' states become the next tissue step (TickSteps) -> each hand's
//   command of the step due (SessionSim::command_for: force vectors for 3-axis channels,
//   per-finger scalars) -> its force guard -> its driver -> the trace notes the replay needs.
// A hand is one haptic device; a session has one or more, ticked together.
// tick() never throws: a lost device, a malformed report, a tissue that falls behind or a trace
// that cannot be written is counted and the session goes on (HapticLoopCounters). stop() sends
// zero through the guard and latches; zero_if_stalled() is the supervisor thread's (run_session
// starts it): both may run on another thread than tick(), and share one lock with it around the
// device, which the supervisor only tries: it never waits for a tick.

#include <algorithm>
#include <array>
#include <atomic>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <span>
#include <string>
#include <string_view>
#include <vector>

#include "bisturi/devices/clock.h"
#include "bisturi/devices/device.h"
#include "bisturi/devices/force_guard.h"
#include "bisturi/devices/trace/guarded_haptic.h"
#include "bisturi/devices/trace/trace_writer.h"
#include "bisturi/runtime/session/device_frame.h"
#include "bisturi/runtime/session/session_sim.h"
#include "clutch.h"
#include "command_slew.h"
#include "step_schedule.h"
#include "tissue_thread.h"

namespace bisturi::runtime {

/// Where a tick's tissue step comes from: the tissue thread live (LiveTickSteps), steps run in
/// place from the trace's notes on replay.
class TickSteps {
 public:
  virtual ~TickSteps() = default;
  /// A hand-over tick's device states (scene frame, one per hand) as the next step over
  /// `ticks` periods, the blood's clock held over it or not.
  virtual TissueThread::Push push(std::span<const devices::HapticState> states, std::uint32_t ticks,
                                  bool blood_held) = 0;
  /// The step tick k uses when step `due` is due (late: an older one).
  virtual TissueThread::TickStep step_for(std::uint64_t k, std::uint64_t due) = 0;
  /// At hand-over tick k, with n ticks per step now: the ticks per step from the next step on.
  virtual std::uint32_t ticks_per_step(std::uint64_t k, std::uint32_t n) = 0;
  /// At hand-over tick k, with the blood's clock held now or not: whether it is held from this
  /// step on.
  virtual bool blood_held(std::uint64_t k, bool now) = 0;
  /// Steps handed over and not finished.
  [[nodiscard]] virtual std::uint64_t backlog() const = 0;
};

/// The live session's steps: the tissue thread, its rate from TissueRateController (adaptive) or
/// fixed.
class LiveTickSteps final : public TickSteps {
 public:
  LiveTickSteps(TissueThread& tissue, bool adaptive, TissueRateController controller)
      : tissue_(tissue), adaptive_(adaptive), controller_(controller) {}
  TissueThread::Push push(std::span<const devices::HapticState> states, std::uint32_t ticks,
                          bool blood_held) override {
    return tissue_.push(states, ticks, blood_held);
  }
  TissueThread::TickStep step_for(std::uint64_t, std::uint64_t due) override {
    return tissue_.step_for(due);
  }
  std::uint32_t ticks_per_step(std::uint64_t, std::uint32_t n) override {
    // A fixed rate stays fixed (the controller would also lower a rate given too low).
    return adaptive_ ? controller_.decide(tissue_.median_step_ms(), cutting()) : n;
  }
  bool blood_held(std::uint64_t, bool now) override {
    // Held once the blood's thread is blood_hold_at steps behind, until it has caught up to half
    // that: the tissue's thread then never waits for it.
    const std::uint64_t behind = tissue_.blood_behind();
    return now ? behind > blood_hold_at / 2 : behind >= blood_hold_at;
  }
  [[nodiscard]] std::uint64_t backlog() const override { return tissue_.pushed() - tissue_.done(); }

  /// Blood steps behind at which the blood's clock holds (SessionOptions::blood_hold_at).
  std::uint64_t blood_hold_at = 4;

 private:
  /// Whether a hand's blade sweeps after the newest finished step.
  [[nodiscard]] bool cutting() const {
    const TickOutput* out = tissue_.output(tissue_.done());
    if (out == nullptr) return false;
    return out->cutting || std::any_of(out->other_hands.begin(), out->other_hands.end(),
                                       [](const HandOutput& h) { return h.cutting; });
  }

  TissueThread& tissue_;
  bool adaptive_;
  TissueRateController controller_;
};

/// What one hand's device went through during the ticks.
struct HandCounters {
  std::uint64_t malformed_reports = 0;
  std::uint64_t guard_latches = 0;     ///< steps on which the guard latched
  std::uint64_t supervisor_zeros = 0;  ///< stalls the supervisor zeroed the output for
  std::uint64_t slewed_ticks = 0;      ///< ticks on which the command slew held a channel back
  /// Ticks on which the device had sent nothing for kSilentAfter (from the first tick when it
  /// never sent anything), the longest such run, and ticks the force guard was latched.
  std::uint64_t silent_ticks = 0;
  std::uint64_t longest_silence_ticks = 0;
  std::uint64_t guard_latched_ticks = 0;
  /// Ticks on which the device said it was not tracked (its forces held at zero), and the
  /// longest such run.
  std::uint64_t untracked_ticks = 0;
  std::uint64_t longest_untracked_ticks = 0;
  /// Ticks with the instrument's tip outside HapticLoopParts' scene box.
  std::uint64_t outside_scene_ticks = 0;
  std::uint64_t clutched_ticks = 0;  ///< ticks with the clutch held (forces zero)
  /// Session time when the device was lost (-1: never), and why.
  double lost_s = -1.0;
  std::string lost_reason;
};

/// What went wrong or degraded during the ticks (read once the haptic thread has stopped).
struct HapticLoopCounters {
  std::uint64_t ticks = 0;
  std::uint64_t late_ticks = 0;          ///< used an older step than the due one
  std::uint64_t max_tissue_backlog = 0;  ///< most steps the tissue was behind at a tick
  std::uint64_t tissue_rate_changes = 0;
  std::uint32_t max_ticks_per_step = 1;
  std::uint64_t dropped_steps = 0;       ///< hand-overs the tissue could not queue (a ring behind)
  std::uint64_t blood_holds = 0;         ///< times the blood's clock stopped (its thread behind)
  bool tissue_failed = false;            ///< a step threw: no new steps, the force is zero
  std::uint64_t display_held_ticks = 0;  ///< ticks held at zero: the headset showed nothing
  std::uint64_t display_stalls = 0;      ///< holds begun because the renderer stopped
  /// Ticks whose step was older than its due step by more than the staleness margin (their
  /// force faded towards zero), and the longest such run.
  std::uint64_t stale_ticks = 0;
  std::uint64_t longest_stale_run = 0;
  std::uint64_t head_malformed_reports = 0;
  /// Session time when the head tracker was lost (-1: never), and why.
  double head_lost_s = -1.0;
  std::string head_lost_reason;
  /// Why the recording stopped (empty: it did not).
  std::string recording_error;
  std::vector<HandCounters> hands;  ///< one per hand
};

enum class TickStatus : std::uint8_t {
  Sent,        ///< the commands went through the guards to the devices
  DeviceLost,  ///< a haptic device is gone: nothing sent to it, its instrument holds its pose
  Stopped,     ///< after stop(): nothing sent
};

/// One hand of a loop: its haptic device (through its force guard) and where it sits.
struct HapticHandParts {
  devices::GuardedHaptic* haptic = nullptr;
  DeviceFrame frame;
  /// The bits of the device's clutch buttons (its driver's ButtonUse::Clutch; 0: none).
  std::uint64_t clutch_buttons = 0;
};

/// The parts a loop drives; all observed, and they must outlive it.
struct HapticLoopParts {
  /// One per hand, in SessionSim's hand order (at least one).
  std::vector<HapticHandParts> hands;
  TickSteps* steps = nullptr;
  const SessionSim* sim = nullptr;
  devices::Clock* clock = nullptr;
  devices::TraceWriter* writer = nullptr;  ///< null: nothing recorded (replay)
  devices::Tracker* head = nullptr;        ///< null: no head tracker (replay)
  /// Live: the twins send the reports due at session time t (hardware sends on its own).
  std::function<void(devices::Nanoseconds)> step_twins;
  /// Live: the head tracker's newest state, for the renderer (not called once it is lost).
  std::function<void(const devices::TrackerState&)> head_state;
  /// Live: false while a headset shows nothing (not visible yet, its session lost): the ticks
  /// send zero then, and each change is noted ("display_hold", "display_live") for the replay.
  /// Null: always shown (files, the replay, which follows the notes: hold_display).
  const std::atomic<bool>* display_live = nullptr;
  /// Live: the clock time by which the renderer must come round again (RenderLoopContext::
  /// display_deadline_ns; -1: not yet). Past it the trainee sees a frozen picture: the ticks
  /// send zero as while the headset shows nothing (the same notes). Null: not watched.
  const std::atomic<std::int64_t>* display_deadline_ns = nullptr;
  /// The box the instruments' tips are expected in (sim metres: the solids' box, widened);
  /// ticks with a tip outside it are counted (a device placed or turned away from the organs).
  /// Empty (min > max): not watched.
  glm::dvec3 scene_box_min_m{1.0}, scene_box_max_m{-1.0};
  /// Ticks a tick may go on using an older step than the due one before its force fades to zero
  /// (over kStaleFadeTicks): a hung tissue thread never leaves a spring to a frozen surface.
  std::uint32_t stale_margin_ticks = 4;
};

class HapticLoop {
 public:
  /// Ticks over which a stale step's force fades to zero (and comes back once steps are due).
  static constexpr std::uint32_t kStaleFadeTicks = 10;
  /// A haptic device that has sent no report for this long counts as silent (the guard zeroes
  /// its forces after its own, shorter, silence timeout).
  static constexpr devices::Nanoseconds kSilentAfter{std::chrono::milliseconds(100)};
  /// `lag`: ticks between a hand-over and the tick that uses its step (step_schedule.h).
  HapticLoop(HapticLoopParts parts, std::uint32_t lag, std::uint32_t ticks_per_step);
  ~HapticLoop();

  /// One tick at session time t (since the session's start). Never throws.
  TickStatus tick(devices::Nanoseconds t) noexcept;
  /// Sends zero through every hand's guard (each recorded as a force command after a
  /// "haptic_stop" note) and latches: later ticks send nothing. Idempotent, never throws.
  void stop() noexcept;
  /// The supervisor: when the last tick began more than `limit` before `now` and a hand's output
  /// has not been zeroed for this stall, sends it zero through its guard (after a
  /// "watchdog_zero" note; the guard latches on the overrun itself). It waits for nothing: first
  /// the driver's zero goes past any write in progress where the transport can
  /// (Device::send_zero_preempting); the guarded zero follows only when the hand's device lock
  /// is free, and when a tick holds it (stuck in the device's I/O) that tick latches the guard,
  /// notes and sends zero once its write returns. Returns true when a zero went out. Never
  /// throws.
  bool zero_if_stalled(devices::Nanoseconds now, devices::Nanoseconds limit) noexcept;
  /// The supervisor's zero for one hand, unconditionally (the replay, where the trace says it
  /// happened).
  void zero_now(std::size_t hand = 0) noexcept;
  /// The replay: the ticks from here send zero (held) or their command, as the trace's
  /// "display_hold" / "display_live" notes say the live session did.
  void hold_display(bool held) noexcept { display_held_ = held; }

  [[nodiscard]] std::size_t hand_count() const { return hands_.size(); }
  /// How long a hand's device has sent nothing, as of the last tick (0 while it sends): for the
  /// watching thread, which says so on the terminal. Any thread.
  [[nodiscard]] double silent_for_s(std::size_t hand = 0) const;
  /// Latches of a hand's force guard so far (each zeros the output): any thread, for the
  /// watching thread, which says so when they keep coming.
  [[nodiscard]] std::uint64_t guard_latches_now(std::size_t hand = 0) const;
  /// How long a hand's device has not been tracked, as of the last tick (0 while it is).
  [[nodiscard]] double untracked_for_s(std::size_t hand = 0) const;
  /// A hand's last command (N, per force component, before the guard).
  [[nodiscard]] const std::vector<double>& command(std::size_t hand = 0) const;
  /// The step the last tick's commands came from (null: none yet, zero commands).
  [[nodiscard]] const TickOutput* step_output() const { return step_output_; }
  /// A hand's device's last state, in the scene frame.
  [[nodiscard]] const devices::HapticState& state(std::size_t hand = 0) const {
    return scene_states_[hand];
  }
  [[nodiscard]] const HapticLoopCounters& counters() const { return counters_; }
  [[nodiscard]] const StepSchedule& schedule() const { return schedule_; }
  [[nodiscard]] bool device_lost(std::size_t hand = 0) const;
  /// What the first hand's device was last given (after the guard): its first component. Any
  /// thread (the supervisor may send between ticks).
  [[nodiscard]] double first_output_N() const;
  /// The largest magnitude of any component any live hand's device was last given.
  [[nodiscard]] double largest_output_N() const;
  [[nodiscard]] bool stopped() const { return stopped_.load(std::memory_order_acquire); }

 private:
  struct Hand;  // one haptic device's link, its watches and what it was sent (haptic_loop.cpp)

  void poll_devices(devices::Nanoseconds t) noexcept;
  void poll_head(devices::Nanoseconds t) noexcept;
  void hand_over(std::uint64_t k) noexcept;
  void send(Hand& hand, devices::Nanoseconds t) noexcept;
  void note(std::string_view text) noexcept;
  void recording_failed(const char* why) noexcept;
  void lose_device(Hand& hand, devices::Nanoseconds t, const std::string& why) noexcept;
  /// Zero through the hand's guard, with its `note_text` first; its device_mutex held.
  void send_zero_locked(Hand& hand, const char* note_text) noexcept;
  /// The supervisor's zero (guard latched on a missed deadline, then zero); device_mutex held.
  bool zero_for_stall_locked(Hand& hand) noexcept;
  /// The hand's published output from its guarded device's; its device_mutex held.
  void publish_output_locked(Hand& hand) noexcept;
  bool zero_hand_if_stalled(Hand& hand) noexcept;

  /// Counts the ticks of an untracked device or a held clutch; true when either holds the
  /// hand's instrument (its force then zero).
  bool watch_instrument(Hand& hand) noexcept;
  /// Notes the device's reports and the guard's latch for the tick at session time t.
  void watch_inputs(Hand& hand, devices::Nanoseconds t) noexcept;
  /// Whether the trainee sees the scene (display_held_), noting each change for the replay.
  void watch_display() noexcept;
  /// The stale-step fade's gain for tick k (`late`: the step used is not the due one).
  double stale_gain(std::uint64_t k, bool late) noexcept;

  HapticLoopParts parts_;
  StepSchedule schedule_;
  /// The tick each of the last kHandOverRing steps was handed over at, by step number: how long
  /// ago the state a step ran on was read (the surface's motion since, SessionSim::command_for).
  static constexpr std::size_t kHandOverRing = 64;
  std::array<std::uint64_t, kHandOverRing> hand_over_ticks_{};
  /// Seconds from the state step j ran on to tick k (at most a few periods: an older step's
  /// surface is not followed further).
  [[nodiscard]] double since_step_s(std::uint64_t k, std::uint64_t j) const noexcept;
  std::vector<std::unique_ptr<Hand>> hands_;
  std::vector<devices::HapticState> scene_states_;  ///< one per hand, in the scene frame
  std::uint64_t fresh_k_ = 0;                       ///< the last tick that used its due step
  std::uint64_t stale_run_ = 0;                     ///< ticks in the current run past the margin
  double stale_gain_ = 1.0;  ///< 1: fresh; falls to 0 while stale, rises again after
  HapticLoopCounters counters_;
  const TickOutput* step_output_ = nullptr;
  bool head_lost_ = false;
  bool display_held_ = false;
  bool blood_held_ = false;  ///< the blood's clock held over the steps handed over now
  std::atomic<bool> recording_{true};
  std::mutex error_mutex_;
  std::uint64_t k_ = 0;
  std::atomic<bool> stopped_{false};
  std::atomic<devices::Nanoseconds::rep> tick_start_ns_{-1};  ///< clock time of the last tick
};

}  // namespace bisturi::runtime
