#pragma once
// The soft-tissue step on its own thread, in lockstep with the haptic ticks without ever making
// them wait. A hand-over tick (every tick, or every n-th: step_schedule.h) hands over the glove
// state it read (push); step j, the j-th SessionSim::tick, runs on exactly that state as soon as
// it is there; a later tick sends the command of the step its StepSchedule says is due, so the
// simulation has a fixed number of periods to finish a step. Which step a tick uses is therefore
// fixed by the tick number, not by the threads' timing, and a replay in virtual time pairs the
// same steps with the same ticks. A step that is not finished in time makes a late tick: it uses
// the newest finished step, and the session notes which in its trace.
//
// Lock-free: two single-producer single-consumer rings (states in, step outputs out) and
// counters; the simulation thread sleeps on an atomic wait while no state is pending. Without a
// thread (threaded = false, lag 0) push() runs the step at once: the tissue in the haptic thread.

#include <array>
#include <atomic>
#include <cstdint>
#include <exception>
#include <functional>
#include <span>
#include <thread>
#include <vector>

#include "bisturi/devices/device.h"
#include "bisturi/runtime/session/session_sim.h"

namespace bisturi::runtime {

class TissueThread {
 public:
  /// Called on the simulation's thread after each step with its output, the device states it
  /// ran on (one per hand) and the step's wall time.
  using AfterStep =
      std::function<void(const TickOutput&, std::span<const devices::HapticState>, double step_ms)>;

  /// `shapes`: one state per hand in its device's shape (poses, joints); every ring slot is made
  /// like them up front, so handing states over never allocates on the haptic thread.
  TissueThread(SessionSim& sim, std::vector<devices::HapticState> shapes, bool threaded,
               bool realtime_priority, AfterStep after_step, std::size_t capacity = 8192);
  /// One hand.
  TissueThread(SessionSim& sim, const devices::HapticState& shape, bool threaded,
               bool realtime_priority, AfterStep after_step, std::size_t capacity = 8192)
      : TissueThread(sim, std::vector<devices::HapticState>{shape}, threaded, realtime_priority,
                     std::move(after_step), capacity) {}
  ~TissueThread();
  TissueThread(const TissueThread&) = delete;
  TissueThread& operator=(const TissueThread&) = delete;

  /// Haptic thread: hands over the next step's haptic state; the step covers `ticks` haptic
  /// periods, the blood's clock held over it or not (SessionSim::tick). Never throws: Behind
  /// when the simulation is a whole ring (capacity steps) behind (the state is not queued),
  /// Failed once a step has thrown (finish() rethrows it).
  enum class Push : std::uint8_t { Queued, Behind, Failed };
  Push push(std::span<const devices::HapticState> states, std::uint32_t ticks = 1,
            bool blood_held = false);
  /// One hand's state.
  Push push(const devices::HapticState& state, std::uint32_t ticks = 1) {
    return push(std::span<const devices::HapticState>(&state, 1), ticks);
  }
  /// Haptic thread: step j's output (1-based) once it is finished, else nullptr.
  [[nodiscard]] const TickOutput* output(std::uint64_t j) const;

  /// The step a tick uses: the due one when it is finished, else the newest finished one (late;
  /// step 0 and no output when none has finished).
  struct TickStep {
    std::uint64_t step = 0;
    const TickOutput* output = nullptr;
    bool late = false;
  };
  [[nodiscard]] TickStep step_for(std::uint64_t due) const;
  /// Median wall time of the last 32 steps on the simulation's thread (the step and after_step),
  /// ms (0 before the first step).
  [[nodiscard]] double median_step_ms() const {
    return median_step_ms_.load(std::memory_order_relaxed);
  }
  [[nodiscard]] std::uint64_t done() const { return done_.load(std::memory_order_acquire); }
  [[nodiscard]] std::uint64_t pushed() const { return pushed_.load(std::memory_order_relaxed); }
  /// The blood's steps queued and not done (SessionSim::blood_behind; any thread).
  [[nodiscard]] std::uint64_t blood_behind() const noexcept { return sim_.blood_behind(); }
  /// Runs the steps still pending and joins the thread; rethrows what the simulation threw.
  void finish();

 private:
  void run();
  void step(std::uint64_t j);
  /// Lets the thread run what is pending, then joins it (no-op without a thread).
  void stop_thread();

  SessionSim& sim_;
  AfterStep after_step_;
  std::size_t capacity_;
  std::vector<std::vector<devices::HapticState>> states_;  ///< per slot, one per hand
  std::vector<std::uint32_t> ticks_;      ///< haptic periods each pending step covers
  std::vector<std::uint8_t> blood_held_;  ///< each pending step's blood_held
  static constexpr std::size_t kRecentSteps = 32;
  std::array<double, kRecentSteps> recent_ms_{};  ///< simulation thread only
  /// The recent steps with no volume asleep, and their median (simulation thread only).
  std::array<double, kRecentSteps> awake_ms_{};
  std::uint64_t awake_steps_ = 0;
  double awake_median_ms_ = 0.0;
  std::atomic<double> median_step_ms_{0.0};
  std::vector<TickOutput> outputs_;
  std::atomic<std::uint64_t> pushed_{0};
  std::atomic<std::uint64_t> done_{0};
  std::atomic<std::uint32_t> wake_{0};
  std::atomic<bool> finishing_{false};
  std::atomic<bool> failed_{false};
  std::atomic<bool> started_{false};  ///< the thread has faulted its heap in
  std::exception_ptr error_;
  std::thread thread_;
};

/// Asks SCHED_FIFO for the calling thread at `below` levels under the haptic thread's priority
/// (half the maximum); false when the system refuses (the thread keeps its priority).
bool request_realtime_priority(int below);

}  // namespace bisturi::runtime
