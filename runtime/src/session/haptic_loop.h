#pragma once
// One haptic tick, the same code for the live session and its replay (session_replay.cpp):
//   the twins send (live) -> the haptic device is polled (through its force guard) and the head
//   tracker too -> the device state goes into the scene frame (DeviceFrame) -> on a hand-over
//   tick it becomes the next tissue step (TickSteps) -> the command of the step due
//   (SessionSim::command_for: force vectors for 3-axis channels, per-finger scalars) -> the
//   force guard -> the driver -> the trace notes the replay needs.
// tick() never throws: a lost device, a malformed report, a tissue that falls behind or a trace
// that cannot be written is counted and the session goes on (HapticLoopCounters). stop() sends
// zero through the guard and latches; zero_if_stalled() is the supervisor thread's (run_session
// starts it): both may run on another thread than tick(), and share one lock with it around the
// device, which the supervisor only tries: it never waits for a tick.

#include <atomic>
#include <cstdint>
#include <functional>
#include <mutex>
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
  /// A hand-over tick's glove state (scene frame) as the next step over `ticks` periods.
  virtual TissueThread::Push push(const devices::HapticState& state, std::uint32_t ticks) = 0;
  /// The step tick k uses when step `due` is due (late: an older one).
  virtual TissueThread::TickStep step_for(std::uint64_t k, std::uint64_t due) = 0;
  /// At hand-over tick k, with n ticks per step now: the ticks per step from the next step on.
  virtual std::uint32_t ticks_per_step(std::uint64_t k, std::uint32_t n) = 0;
  /// Steps handed over and not finished.
  [[nodiscard]] virtual std::uint64_t backlog() const = 0;
};

/// The live session's steps: the tissue thread, its rate from TissueRateController (adaptive) or
/// fixed.
class LiveTickSteps final : public TickSteps {
 public:
  LiveTickSteps(TissueThread& tissue, bool adaptive, TissueRateController controller)
      : tissue_(tissue), adaptive_(adaptive), controller_(controller) {}
  TissueThread::Push push(const devices::HapticState& state, std::uint32_t ticks) override {
    return tissue_.push(state, ticks);
  }
  TissueThread::TickStep step_for(std::uint64_t, std::uint64_t due) override {
    return tissue_.step_for(due);
  }
  std::uint32_t ticks_per_step(std::uint64_t, std::uint32_t n) override {
    // A fixed rate stays fixed (the controller would also lower a rate given too low).
    return adaptive_ ? controller_.decide(tissue_.median_step_ms()) : n;
  }
  [[nodiscard]] std::uint64_t backlog() const override { return tissue_.pushed() - tissue_.done(); }

 private:
  TissueThread& tissue_;
  bool adaptive_;
  TissueRateController controller_;
};

/// What went wrong or degraded during the ticks (read once the haptic thread has stopped).
struct HapticLoopCounters {
  std::uint64_t ticks = 0;
  std::uint64_t late_ticks = 0;          ///< used an older step than the due one
  std::uint64_t max_tissue_backlog = 0;  ///< most steps the tissue was behind at a tick
  std::uint64_t tissue_rate_changes = 0;
  std::uint32_t max_ticks_per_step = 1;
  std::uint64_t dropped_steps = 0;  ///< hand-overs the tissue could not queue (a ring behind)
  bool tissue_failed = false;       ///< a step threw: no new steps, the force is zero
  std::uint64_t malformed_reports = 0;
  std::uint64_t guard_latches = 0;       ///< steps on which the guard latched
  std::uint64_t supervisor_zeros = 0;    ///< stalls the supervisor zeroed the output for
  std::uint64_t display_held_ticks = 0;  ///< ticks held at zero: the headset showed nothing
  std::uint64_t display_stalls = 0;      ///< holds begun because the renderer stopped
  /// Ticks whose step was older than its due step by more than the staleness margin (their
  /// force faded towards zero), and the longest such run.
  std::uint64_t stale_ticks = 0;
  std::uint64_t longest_stale_run = 0;
  std::uint64_t slewed_ticks = 0;  ///< ticks on which the command slew held a channel back
  /// Ticks on which the haptic device had sent nothing for kSilentAfter (from the first tick when
  /// it never sent anything), the longest such run, and ticks the force guard was latched.
  std::uint64_t silent_ticks = 0;
  std::uint64_t longest_silence_ticks = 0;
  /// Ticks on which the haptic device said it was not tracked (its forces held at zero), and
  /// the longest such run.
  std::uint64_t untracked_ticks = 0;
  std::uint64_t longest_untracked_ticks = 0;
  /// Ticks with the instrument's tip outside HapticLoopParts' scene box.
  std::uint64_t outside_scene_ticks = 0;
  std::uint64_t clutched_ticks = 0;  ///< ticks with the clutch held (forces zero)
  std::uint64_t guard_latched_ticks = 0;
  /// Session time when the haptic device / head tracker was lost (-1: never), and why.
  double haptic_lost_s = -1.0;
  std::string haptic_lost_reason;
  double head_lost_s = -1.0;
  std::string head_lost_reason;
  /// Why the recording stopped (empty: it did not).
  std::string recording_error;
};

enum class TickStatus : std::uint8_t {
  Sent,        ///< the command went through the guard to the device
  DeviceLost,  ///< the haptic device is gone: nothing sent, the instrument holds its pose
  Stopped,     ///< after stop(): nothing sent
};

/// The parts a loop drives; all observed, and they must outlive it.
struct HapticLoopParts {
  devices::GuardedHaptic* haptic = nullptr;
  TickSteps* steps = nullptr;
  const SessionSim* sim = nullptr;
  DeviceFrame frame;
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
  /// The box the instrument's tip is expected in (sim metres: the solids' box, widened); ticks
  /// with the tip outside it are counted (a device placed or turned away from the organs).
  /// Empty (min > max): not watched.
  glm::dvec3 scene_box_min_m{1.0}, scene_box_max_m{-1.0};
  /// The bits of the haptic device's clutch buttons (its driver's ButtonUse::Clutch; 0: none).
  std::uint64_t clutch_buttons = 0;
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

  /// One tick at session time t (since the session's start). Never throws.
  TickStatus tick(devices::Nanoseconds t) noexcept;
  /// Sends zero through the guard (recorded as a force command after a "haptic_stop" note) and
  /// latches: later ticks send nothing. Idempotent, never throws.
  void stop() noexcept;
  /// The supervisor: when the last tick began more than `limit` before `now` and the output has
  /// not been zeroed for this stall, sends zero through the guard (after a "watchdog_zero" note;
  /// the guard latches on the overrun itself). It waits for nothing: first the driver's zero goes
  /// past any write in progress where the transport can (Device::send_zero_preempting); the
  /// guarded zero follows only when the device lock is free, and when a tick holds it (stuck in
  /// the device's I/O) that tick latches the guard, notes and sends zero once its write returns.
  /// Returns true when a zero went out. Never throws.
  bool zero_if_stalled(devices::Nanoseconds now, devices::Nanoseconds limit) noexcept;
  /// The supervisor's zero, unconditionally (the replay, where the trace says it happened).
  void zero_now() noexcept;
  /// The replay: the ticks from here send zero (held) or their command, as the trace's
  /// "display_hold" / "display_live" notes say the live session did.
  void hold_display(bool held) noexcept { display_held_ = held; }

  /// How long the haptic device has sent nothing, as of the last tick (0 while it sends): for
  /// the watching thread, which says so on the terminal. Any thread.
  [[nodiscard]] double silent_for_s() const {
    return silent_for_s_.load(std::memory_order_relaxed);
  }
  /// Latches of the force guard so far (each zeros the output): any thread, for the watching
  /// thread, which says so when they keep coming.
  [[nodiscard]] std::uint64_t guard_latches_now() const {
    return guard_latches_now_.load(std::memory_order_relaxed);
  }
  /// How long the haptic device has not been tracked, as of the last tick (0 while it is).
  [[nodiscard]] double untracked_for_s() const {
    return untracked_for_s_.load(std::memory_order_relaxed);
  }
  /// The last tick's command (N, per force component, before the guard).
  [[nodiscard]] const std::vector<double>& command() const { return command_; }
  /// The step the last tick's command came from (null: none yet, a zero command).
  [[nodiscard]] const TickOutput* step_output() const { return step_output_; }
  /// The haptic device's last state, in the scene frame.
  [[nodiscard]] const devices::HapticState& state() const { return scene_state_; }
  [[nodiscard]] const HapticLoopCounters& counters() const { return counters_; }
  [[nodiscard]] const StepSchedule& schedule() const { return schedule_; }
  [[nodiscard]] bool device_lost() const { return lost_; }
  /// What the device was last given (after the guard): its first component and the largest
  /// magnitude of any. Any thread (the supervisor may send between ticks).
  [[nodiscard]] double first_output_N() const {
    return first_output_N_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] double largest_output_N() const {
    return largest_output_N_.load(std::memory_order_acquire);
  }
  [[nodiscard]] bool stopped() const { return stopped_.load(std::memory_order_acquire); }

 private:
  void poll_devices(devices::Nanoseconds t) noexcept;
  void hand_over(std::uint64_t k) noexcept;
  void send(devices::Nanoseconds t) noexcept;
  void note(std::string_view text) noexcept;
  void recording_failed(const char* why) noexcept;
  void lose_device(devices::Nanoseconds t, const std::string& why) noexcept;
  /// Zero through the guard, with `note_text` first; device_mutex_ held.
  void send_zero_locked(const char* note_text) noexcept;
  /// The supervisor's zero (guard latched on a missed deadline, then zero); device_mutex_ held.
  bool zero_for_stall_locked() noexcept;
  /// first_output_N_ / largest_output_N_ from the guarded device's output; device_mutex_ held.
  void publish_output_locked() noexcept;

  /// Counts the ticks of an untracked device or a held clutch; true when either holds the
  /// instrument (its force then zero).
  bool watch_instrument() noexcept;
  /// Whether the trainee sees the scene (display_held_), noting each change for the replay.
  void watch_display() noexcept;
  /// The stale-step fade on command_ (tick k, `late`: the step used is not the due one).
  void fade_if_stale(std::uint64_t k, bool late) noexcept;

  HapticLoopParts parts_;
  StepSchedule schedule_;
  CommandSlew slew_;
  std::uint64_t fresh_k_ = 0;               ///< the last tick that used its due step
  std::uint64_t last_reports_ = 0;          ///< the device's report count at the last tick
  devices::Nanoseconds last_report_t_{-1};  ///< session time a new report was last seen
  std::uint64_t silence_run_ = 0;
  std::atomic<double> silent_for_s_{0.0};
  std::uint64_t untracked_run_ = 0;
  Clutch clutch_;
  std::atomic<double> untracked_for_s_{0.0};
  std::atomic<std::uint64_t> guard_latches_now_{0};
  /// Notes the device's reports and the guard's latch for the tick at session time t.
  void watch_inputs(devices::Nanoseconds t) noexcept;
  std::uint64_t stale_run_ = 0;  ///< ticks in the current run past the margin
  double stale_gain_ = 1.0;      ///< 1: fresh; falls to 0 while stale, rises again after
  HapticLoopCounters counters_;
  std::vector<double> command_;
  std::vector<double> zeros_;
  devices::HapticState scene_state_;
  const TickOutput* step_output_ = nullptr;
  bool lost_ = false;
  bool head_lost_ = false;
  bool guard_latched_ = false;  ///< the guard's state at this tick's poll
  bool display_held_ = false;
  std::atomic<bool> recording_{true};
  std::mutex error_mutex_;
  std::uint64_t k_ = 0;

  std::mutex device_mutex_;  ///< the guard and the device's output: tick, stop, supervisor
  std::atomic<bool> stopped_{false};
  std::atomic<devices::Nanoseconds::rep> tick_start_ns_{-1};  ///< clock time of the last tick
  std::atomic<bool> zeroed_for_stall_{false};
  /// A zero went past the tick's stuck device I/O: the tick finishes the job when it returns.
  std::atomic<bool> preempted_{false};
  std::atomic<bool> device_live_{true};  ///< lost_, for the supervisor's lock-free path
  std::atomic<double> first_output_N_{0.0}, largest_output_N_{0.0};
};

}  // namespace bisturi::runtime
