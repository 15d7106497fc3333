// One haptic tick, live and on replay (see haptic_loop.h).

#include "haptic_loop.h"

#include <algorithm>
#include <exception>

#include <glm/vector_relational.hpp>

#include "lockstep_notes.h"

namespace bisturi::runtime {

namespace {

double seconds(devices::Nanoseconds t) {
  return static_cast<double>(t.count()) * 1e-9;
}

}  // namespace

HapticLoop::HapticLoop(HapticLoopParts parts, std::uint32_t lag, std::uint32_t ticks_per_step)
    : parts_(std::move(parts)),
      schedule_(lag, ticks_per_step),
      slew_(parts_.haptic->guard().channels(), parts_.sim->haptic_period_ms() * 1e-3),
      clutch_(parts_.clutch_buttons),
      command_(parts_.sim->command_size(), 0.0),
      zeros_(parts_.sim->command_size(), 0.0) {
  counters_.max_ticks_per_step = ticks_per_step;
  const devices::Capabilities& caps = parts_.haptic->device().capabilities();
  // The state the loop copies is made in the device's shape now: a tick never allocates.
  scene_state_.end_effector_poses.resize(caps.end_effectors);
  scene_state_.finger_joint_angles_rad.resize(caps.finger_joints.size());
}

void HapticLoop::note(std::string_view text) noexcept {
  if (parts_.writer == nullptr || !recording_.load(std::memory_order_acquire)) return;
  try {
    parts_.writer->note(parts_.clock->now().count(), text);
  } catch (const std::exception& e) {
    recording_failed(e.what());
  }
}

void HapticLoop::recording_failed(const char* why) noexcept {
  // The trace is lost from here on; the session is not.
  std::lock_guard lock(error_mutex_);
  if (!recording_.exchange(false)) return;
  try {
    counters_.recording_error = why;
  } catch (...) {  // no memory for the message: the flag says it all
  }
}

void HapticLoop::lose_device(devices::Nanoseconds t, const std::string& why) noexcept {
  if (lost_) return;
  lost_ = true;
  device_live_.store(false, std::memory_order_release);
  counters_.haptic_lost_s = seconds(t);
  counters_.haptic_lost_reason = why;
}

void HapticLoop::poll_devices(devices::Nanoseconds t) noexcept {
  if (parts_.step_twins) parts_.step_twins(t);
  if (!lost_) {
    std::lock_guard lock(device_mutex_);
    try {
      parts_.haptic->poll(std::chrono::microseconds(0));
    } catch (const devices::DeviceDisconnected& e) {
      lose_device(t, e.what());  // the guard has latched: its output is zero
    } catch (const devices::ProtocolError&) {
      ++counters_.malformed_reports;  // dropped; the state keeps its previous values
    } catch (const devices::TraceError& e) {
      recording_failed(e.what());
    } catch (const std::exception& e) {
      // Any other failure of the device (an I/O error of its transport) loses it too.
      parts_.haptic->guard().device_disconnected();
      lose_device(t, e.what());
    }
    // Read under the lock: the supervisor may latch the guard while a slow tick runs.
    guard_latched_ = parts_.haptic->guard().state() == devices::GuardState::Latched;
  }
  if (parts_.head != nullptr && !head_lost_) {
    try {
      parts_.head->poll(std::chrono::microseconds(0));
    } catch (const devices::ProtocolError&) {
      ++counters_.malformed_reports;
    } catch (const std::exception& e) {
      // The view holds the last pose the tracker gave.
      head_lost_ = true;
      counters_.head_lost_s = seconds(t);
      counters_.head_lost_reason = e.what();
    }
    if (!head_lost_ && parts_.head_state) parts_.head_state(parts_.head->state());
  }
  // A lost device keeps its last state: the instrument holds where it was.
  if (!lost_) {
    parts_.frame.to_scene(parts_.haptic->device().state(), scene_state_);
    (void)clutch_.apply(scene_state_);
  }
}

void HapticLoop::hand_over(std::uint64_t k) noexcept {
  // A hand-over tick gives its state to the tissue as the next step (and may change the steps'
  // length, noted in the trace).
  if (!schedule_.hands_over(k)) return;
  switch (parts_.steps->push(scene_state_, schedule_.handed_over_ticks())) {
    case TissueThread::Push::Queued:
      break;
    case TissueThread::Push::Behind:
      // Never taken: the steps after it keep the tissue's own numbering, so they come due.
      ++counters_.dropped_steps;
      note(dropped_step_note(k, schedule_.steps()));
      schedule_.forget_hand_over();
      break;
    case TissueThread::Push::Failed:
      counters_.tissue_failed = true;
      break;
  }
  const std::uint32_t n = parts_.steps->ticks_per_step(k, schedule_.ticks_per_step());
  if (n != schedule_.ticks_per_step()) {
    schedule_.set_ticks_per_step(k, n);
    ++counters_.tissue_rate_changes;
    counters_.max_ticks_per_step = std::max(counters_.max_ticks_per_step, n);
    note(tissue_rate_note(k, n));
  }
}

void HapticLoop::send(devices::Nanoseconds t) noexcept {
  std::lock_guard lock(device_mutex_);
  if (stopped_.load(std::memory_order_acquire)) return;
  try {
    const devices::GuardStep g = parts_.haptic->send(command_);
    if (g.latched != devices::Fault::None) {
      ++counters_.guard_latches;
      guard_latches_now_.fetch_add(1, std::memory_order_relaxed);
    }
    publish_output_locked();
  } catch (const devices::DeviceDisconnected& e) {
    lose_device(t, e.what());
  } catch (const devices::TraceError& e) {
    // The command went out (GuardedHaptic sends first); only its record is lost.
    recording_failed(e.what());
  } catch (const std::exception& e) {
    parts_.haptic->guard().device_disconnected();
    lose_device(t, e.what());
  }
}

TickStatus HapticLoop::tick(devices::Nanoseconds t) noexcept {
  tick_start_ns_.store(parts_.clock->now().count(), std::memory_order_release);
  zeroed_for_stall_.store(false, std::memory_order_release);
  ++counters_.ticks;
  if (stopped_.load(std::memory_order_acquire)) return TickStatus::Stopped;
  poll_devices(t);
  watch_inputs(t);
  if (parts_.scene_box_min_m.x <= parts_.scene_box_max_m.x) {
    const glm::dvec3 tip = SessionSim::tip_of(scene_state_);
    if (glm::any(glm::lessThan(tip, parts_.scene_box_min_m)) ||
        glm::any(glm::greaterThan(tip, parts_.scene_box_max_m)))
      ++counters_.outside_scene_ticks;
  }

  // Every tick sends the command of the step due (or, when that step is late, the newest one,
  // noted in the trace for the replay).
  const std::uint64_t k = ++k_;
  hand_over(k);
  const TissueThread::TickStep use = parts_.steps->step_for(k, schedule_.due(k));
  counters_.max_tissue_backlog = std::max(counters_.max_tissue_backlog, parts_.steps->backlog());
  if (use.late) {
    ++counters_.late_ticks;
    note(late_tick_note(k, use.step));
  }
  step_output_ = use.output;
  if (step_output_ != nullptr && !counters_.tissue_failed) {
    parts_.sim->command_for(*step_output_, SessionSim::tip_of(scene_state_), command_);
  } else {
    std::fill(command_.begin(), command_.end(), 0.0);
  }
  fade_if_stale(k, use.late);
  const bool instrument_held = watch_instrument();
  watch_display();
  // Held at zero, the slew starts again from zero (forces come back as a ramp).
  if (instrument_held || display_held_) {
    std::fill(command_.begin(), command_.end(), 0.0);
    slew_.reset();
    if (display_held_) ++counters_.display_held_ticks;
  } else if (slew_.apply(command_)) {
    ++counters_.slewed_ticks;
  }
  const bool was_lost = lost_;
  if (!lost_) send(t);
  if (preempted_.exchange(false, std::memory_order_acq_rel)) {
    // The supervisor's zero went past this tick's stuck write: latch, note and zero here too,
    // so the guard holds zero from now on and the trace says where it happened.
    std::lock_guard lock(device_mutex_);
    (void)zero_for_stall_locked();
  }
  // A tick without a force command is noted, so the replay counts it too.
  if (was_lost) note("tick");
  if (stopped_.load(std::memory_order_acquire)) return TickStatus::Stopped;
  return lost_ ? TickStatus::DeviceLost : TickStatus::Sent;
}

void HapticLoop::watch_inputs(devices::Nanoseconds t) noexcept {
  const std::uint64_t reports = parts_.haptic->device().state().reports;
  if (reports != last_reports_ || last_report_t_.count() < 0) {
    last_report_t_ = t;
    last_reports_ = reports;
  }
  const devices::Nanoseconds quiet = t - last_report_t_;
  if (!lost_ && quiet > kSilentAfter) {
    ++counters_.silent_ticks;
    counters_.longest_silence_ticks = std::max(counters_.longest_silence_ticks, ++silence_run_);
    silent_for_s_.store(seconds(quiet), std::memory_order_relaxed);
  } else {
    silence_run_ = 0;
    silent_for_s_.store(0.0, std::memory_order_relaxed);
  }
  if (guard_latched_) ++counters_.guard_latched_ticks;
}

bool HapticLoop::watch_instrument() noexcept {
  // A device that does not know where it is: its instrument holds its last pose, and a force
  // computed there would push the hand towards a place it may no longer be. The same while the
  // clutch is held: the hand moves the handle, not the instrument.
  if (clutch_.held()) ++counters_.clutched_ticks;
  const bool untracked = !lost_ && !parts_.haptic->device().state().tracked;
  if (untracked) {
    ++counters_.untracked_ticks;
    counters_.longest_untracked_ticks =
        std::max(counters_.longest_untracked_ticks, ++untracked_run_);
  } else {
    untracked_run_ = 0;
  }
  untracked_for_s_.store(
      static_cast<double>(untracked_run_) * parts_.sim->haptic_period_ms() * 1e-3,
      std::memory_order_relaxed);
  return clutch_.held() || untracked;
}

void HapticLoop::watch_display() noexcept {
  // No force the trainee cannot see the cause of: while the headset shows nothing, or the
  // renderer is past its deadline (a frozen picture), zero; each change is noted for the replay.
  if (parts_.display_live == nullptr) return;
  bool held = !parts_.display_live->load(std::memory_order_acquire);
  if (parts_.display_deadline_ns != nullptr) {
    const std::int64_t deadline = parts_.display_deadline_ns->load(std::memory_order_acquire);
    if (deadline >= 0 && parts_.clock->now().count() > deadline) {
      held = true;
      if (!display_held_) ++counters_.display_stalls;
    }
  }
  if (held != display_held_) note(held ? "display_hold" : "display_live");
  display_held_ = held;
}

void HapticLoop::fade_if_stale(std::uint64_t k, bool late) noexcept {
  if (!late) fresh_k_ = k;
  const bool stale = late && k - fresh_k_ > parts_.stale_margin_ticks;
  if (stale) {
    ++counters_.stale_ticks;
    counters_.longest_stale_run = std::max(counters_.longest_stale_run, ++stale_run_);
  } else {
    stale_run_ = 0;
  }
  constexpr double kFadeStep = 1.0 / kStaleFadeTicks;
  stale_gain_ = std::clamp(stale_gain_ + (stale ? -kFadeStep : kFadeStep), 0.0, 1.0);
  if (stale_gain_ < 1.0) {
    for (double& c : command_)
      c *= stale_gain_;
  }
}

void HapticLoop::send_zero_locked(const char* note_text) noexcept {
  note(note_text);
  try {
    parts_.haptic->send(zeros_);
  } catch (const std::exception&) {
    // Gone or unrecordable: the guard is latched either way, nothing more can be sent.
    parts_.haptic->guard().device_disconnected();
  }
  publish_output_locked();
}

void HapticLoop::publish_output_locked() noexcept {
  const std::vector<double>& output = parts_.haptic->last_output_N();
  double largest = 0.0;
  for (const double f : output)
    largest = std::max(largest, std::abs(f));
  first_output_N_.store(output.empty() ? 0.0 : output[0], std::memory_order_relaxed);
  largest_output_N_.store(largest, std::memory_order_release);
}

void HapticLoop::stop() noexcept {
  std::lock_guard lock(device_mutex_);
  if (stopped_.exchange(true, std::memory_order_acq_rel)) return;
  // Latched first, so the zero goes out at once (a zero command alone is rate-limited down).
  parts_.haptic->guard().device_disconnected();
  if (!lost_) send_zero_locked("haptic_stop");
}

bool HapticLoop::zero_if_stalled(devices::Nanoseconds now, devices::Nanoseconds limit) noexcept {
  const auto start = tick_start_ns_.load(std::memory_order_acquire);
  if (start < 0 || now.count() - start <= limit.count()) return false;
  if (zeroed_for_stall_.load(std::memory_order_acquire)) return false;
  if (stopped_.load(std::memory_order_acquire) || !device_live_.load(std::memory_order_acquire))
    return false;
  // The zero that waits for nothing goes first, where the transport has one: past a tick stuck
  // in the device's write, and ahead of this thread's own write below, which a device that has
  // stopped taking reports would hold as well.
  const bool preempted = parts_.haptic->device().send_zero_preempting();
  if (preempted) {
    first_output_N_.store(0.0, std::memory_order_relaxed);
    largest_output_N_.store(0.0, std::memory_order_release);
  }
  std::unique_lock lock(device_mutex_, std::try_to_lock);
  if (!lock.owns_lock()) {
    // The tick holds the device. Without a preempting zero the next look tries again (the zero
    // then goes out when the tick lets go); with one, the tick finishes the job.
    if (!preempted) return false;
    zeroed_for_stall_.store(true, std::memory_order_release);
    preempted_.store(true, std::memory_order_release);
    return true;
  }
  if (zeroed_for_stall_.exchange(true, std::memory_order_acq_rel)) return preempted;
  return zero_for_stall_locked() || preempted;
}

void HapticLoop::zero_now() noexcept {
  std::lock_guard lock(device_mutex_);
  (void)zero_for_stall_locked();
}

bool HapticLoop::zero_for_stall_locked() noexcept {
  if (stopped_.load(std::memory_order_acquire) || lost_) return false;
  // Latched first, so the zero goes out at once (a zero command alone is rate-limited down).
  parts_.haptic->guard().deadline_missed();
  send_zero_locked("watchdog_zero");
  ++counters_.supervisor_zeros;
  return true;
}

}  // namespace bisturi::runtime
