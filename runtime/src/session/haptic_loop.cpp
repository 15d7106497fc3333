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

/// One hand's device: its link through the guard, what the tick watches on it and what it was
/// last sent. The supervisor reads the atomics and tries the lock; the rest is the tick's.
struct HapticLoop::Hand {
  Hand(std::size_t hand_index, const HapticHandParts& hand_parts, const SessionSim& sim,
       HandCounters& hand_counters)
      : index(hand_index),
        parts(hand_parts),
        counters(hand_counters),
        slew(hand_parts.haptic->guard().channels(), sim.haptic_period_ms() * 1e-3),
        clutch(hand_parts.clutch_buttons),
        command(sim.command_size(hand_index), 0.0),
        zeros(sim.command_size(hand_index), 0.0) {}
  std::size_t index;
  HapticHandParts parts;
  HandCounters& counters;  ///< the loop's counters().hands[index]
  CommandSlew slew;
  Clutch clutch;
  std::vector<double> command;
  std::vector<double> zeros;
  std::uint64_t last_reports = 0;          ///< the device's report count at the last tick
  devices::Nanoseconds last_report_t{-1};  ///< session time a new report was last seen
  std::uint64_t silence_run = 0;
  std::uint64_t untracked_run = 0;
  bool lost = false;
  bool guard_latched = false;  ///< the guard's state at this tick's poll
  std::atomic<double> silent_for_s{0.0};
  std::atomic<double> untracked_for_s{0.0};
  std::atomic<std::uint64_t> guard_latches_now{0};
  std::mutex device_mutex;  ///< the guard and the device's output: tick, stop, supervisor
  std::atomic<bool> zeroed_for_stall{false};
  /// A zero went past the tick's stuck device I/O: the tick finishes the job when it returns.
  std::atomic<bool> preempted{false};
  std::atomic<bool> device_live{true};  ///< !lost, for the supervisor's lock-free path
  std::atomic<double> first_output_N{0.0}, largest_output_N{0.0};
  /// The notes before this hand's zeros: the first hand's plain (as one-handed traces have them),
  /// the others' with their hand number.
  std::string stop_note, watchdog_note;
};

HapticLoop::HapticLoop(HapticLoopParts parts, std::uint32_t lag, std::uint32_t ticks_per_step)
    : parts_(std::move(parts)), schedule_(lag, ticks_per_step) {
  counters_.max_ticks_per_step = ticks_per_step;
  counters_.hands.resize(parts_.hands.size());  // never resized again: the hands refer to them
  for (std::size_t i = 0; i < parts_.hands.size(); ++i) {
    hands_.push_back(std::make_unique<Hand>(i, parts_.hands[i], *parts_.sim, counters_.hands[i]));
    Hand& hand = *hands_.back();
    hand.stop_note = hand_note("haptic_stop", i);
    hand.watchdog_note = hand_note("watchdog_zero", i);
    const devices::Capabilities& caps = hand.parts.haptic->device().capabilities();
    // The state the loop copies is made in the device's shape now: a tick never allocates.
    devices::HapticState shape;
    shape.end_effector_poses.resize(caps.end_effectors);
    shape.finger_joint_angles_rad.resize(caps.finger_joints.size());
    scene_states_.push_back(std::move(shape));
  }
}

HapticLoop::~HapticLoop() = default;

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

void HapticLoop::lose_device(Hand& hand, devices::Nanoseconds t, const std::string& why) noexcept {
  if (hand.lost) return;
  hand.lost = true;
  hand.device_live.store(false, std::memory_order_release);
  hand.counters.lost_s = seconds(t);
  try {
    hand.counters.lost_reason = why;
  } catch (...) {
  }
}

void HapticLoop::poll_devices(devices::Nanoseconds t) noexcept {
  if (parts_.step_twins) parts_.step_twins(t);
  for (const auto& h : hands_) {
    Hand& hand = *h;
    if (hand.lost) continue;
    devices::GuardedHaptic& haptic = *hand.parts.haptic;
    std::lock_guard lock(hand.device_mutex);
    try {
      haptic.poll(std::chrono::microseconds(0));
    } catch (const devices::DeviceDisconnected& e) {
      lose_device(hand, t, e.what());  // the guard has latched: its output is zero
    } catch (const devices::ProtocolError&) {
      ++hand.counters.malformed_reports;  // dropped; the state keeps its previous values
    } catch (const devices::TraceError& e) {
      recording_failed(e.what());
    } catch (const std::exception& e) {
      // Any other failure of the device (an I/O error of its transport) loses it too.
      haptic.guard().device_disconnected();
      lose_device(hand, t, e.what());
    }
    // Read under the lock: the supervisor may latch the guard while a slow tick runs.
    hand.guard_latched = haptic.guard().state() == devices::GuardState::Latched;
  }
  poll_head(t);
  // A lost device keeps its last state: the instrument holds where it was.
  for (const auto& h : hands_) {
    Hand& hand = *h;
    if (hand.lost) continue;
    hand.parts.frame.to_scene(hand.parts.haptic->device().state(), scene_states_[hand.index]);
    (void)hand.clutch.apply(scene_states_[hand.index]);
  }
}

void HapticLoop::poll_head(devices::Nanoseconds t) noexcept {
  if (parts_.head == nullptr || head_lost_) return;
  try {
    parts_.head->poll(std::chrono::microseconds(0));
  } catch (const devices::ProtocolError&) {
    ++counters_.head_malformed_reports;
  } catch (const std::exception& e) {
    // The view holds the last pose the tracker gave.
    head_lost_ = true;
    counters_.head_lost_s = seconds(t);
    try {
      counters_.head_lost_reason = e.what();
    } catch (...) {
    }
  }
  if (!head_lost_ && parts_.head_state) parts_.head_state(parts_.head->state());
}

void HapticLoop::hand_over(std::uint64_t k) noexcept {
  // A hand-over tick gives its states to the tissue as the next step (and may change the steps'
  // length, noted in the trace).
  if (!schedule_.hands_over(k)) return;
  const bool held = parts_.steps->blood_held(k, blood_held_);
  if (held != blood_held_) {
    blood_held_ = held;
    if (held) ++counters_.blood_holds;
    note(blood_hold_note(k, held));
  }
  switch (parts_.steps->push(scene_states_, schedule_.handed_over_ticks(), held)) {
    case TissueThread::Push::Queued:
      hand_over_ticks_[schedule_.steps() % kHandOverRing] = k;
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

double HapticLoop::since_step_s(std::uint64_t k, std::uint64_t j) const noexcept {
  // The surface's motion is followed for a few periods at most: a step much older than due is
  // fading out (stale_gain), and its surface's velocity says little about now.
  constexpr std::uint64_t kMostTicks = 8;
  if (j == 0 || schedule_.steps() - j >= kHandOverRing) return 0.0;
  const std::uint64_t handed = hand_over_ticks_[j % kHandOverRing];
  const std::uint64_t ticks = k > handed ? std::min(k - handed, kMostTicks) : 0;
  return static_cast<double>(ticks) * parts_.sim->haptic_period_ms() * 1e-3;
}

void HapticLoop::send(Hand& hand, devices::Nanoseconds t) noexcept {
  std::lock_guard lock(hand.device_mutex);
  if (stopped_.load(std::memory_order_acquire)) return;
  devices::GuardedHaptic& haptic = *hand.parts.haptic;
  try {
    const devices::GuardStep g = haptic.send(hand.command);
    if (g.latched != devices::Fault::None) {
      ++hand.counters.guard_latches;
      hand.guard_latches_now.fetch_add(1, std::memory_order_relaxed);
    }
    publish_output_locked(hand);
  } catch (const devices::DeviceDisconnected& e) {
    lose_device(hand, t, e.what());
  } catch (const devices::TraceError& e) {
    // The command went out (GuardedHaptic sends first); only its record is lost.
    recording_failed(e.what());
  } catch (const std::exception& e) {
    haptic.guard().device_disconnected();
    lose_device(hand, t, e.what());
  }
}

TickStatus HapticLoop::tick(devices::Nanoseconds t) noexcept {
  tick_start_ns_.store(parts_.clock->now().count(), std::memory_order_release);
  for (const auto& h : hands_)
    h->zeroed_for_stall.store(false, std::memory_order_release);
  ++counters_.ticks;
  if (stopped_.load(std::memory_order_acquire)) return TickStatus::Stopped;
  poll_devices(t);
  for (const auto& h : hands_) {
    watch_inputs(*h, t);
    if (parts_.scene_box_min_m.x <= parts_.scene_box_max_m.x) {
      const glm::dvec3 tip = SessionSim::tip_of(scene_states_[h->index]);
      if (glm::any(glm::lessThan(tip, parts_.scene_box_min_m)) ||
          glm::any(glm::greaterThan(tip, parts_.scene_box_max_m)))
        ++h->counters.outside_scene_ticks;
    }
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
  const double gain = stale_gain(k, use.late);
  watch_display();
  bool any_lost = false;
  for (const auto& h : hands_) {
    Hand& hand = *h;
    if (step_output_ != nullptr && !counters_.tissue_failed) {
      parts_.sim->command_for(*step_output_, hand.index,
                              SessionSim::tip_of(scene_states_[hand.index]), hand.command,
                              since_step_s(k, use.step));
    } else {
      std::fill(hand.command.begin(), hand.command.end(), 0.0);
    }
    if (gain < 1.0) {
      for (double& c : hand.command)
        c *= gain;
    }
    const bool instrument_held = watch_instrument(hand);
    // Held at zero, the slew starts again from zero (forces come back as a ramp).
    if (instrument_held || display_held_) {
      std::fill(hand.command.begin(), hand.command.end(), 0.0);
      hand.slew.reset();
    } else if (hand.slew.apply(hand.command)) {
      ++hand.counters.slewed_ticks;
    }
    const bool was_lost = hand.lost;
    if (!hand.lost) send(hand, t);
    if (hand.preempted.exchange(false, std::memory_order_acq_rel)) {
      // The supervisor's zero went past this tick's stuck write: latch, note and zero here too,
      // so the guard holds zero from now on and the trace says where it happened.
      std::lock_guard lock(hand.device_mutex);
      (void)zero_for_stall_locked(hand);
    }
    // A tick without the first hand's force command is noted, so the replay counts it too.
    if (was_lost && hand.index == 0) note("tick");
    any_lost = any_lost || hand.lost;
  }
  if (display_held_) ++counters_.display_held_ticks;
  if (stopped_.load(std::memory_order_acquire)) return TickStatus::Stopped;
  return any_lost ? TickStatus::DeviceLost : TickStatus::Sent;
}

void HapticLoop::watch_inputs(Hand& hand, devices::Nanoseconds t) noexcept {
  const std::uint64_t reports = hand.parts.haptic->device().state().reports;
  if (reports != hand.last_reports || hand.last_report_t.count() < 0) {
    hand.last_report_t = t;
    hand.last_reports = reports;
  }
  const devices::Nanoseconds quiet = t - hand.last_report_t;
  HandCounters& c = hand.counters;
  if (!hand.lost && quiet > kSilentAfter) {
    ++c.silent_ticks;
    c.longest_silence_ticks = std::max(c.longest_silence_ticks, ++hand.silence_run);
    hand.silent_for_s.store(seconds(quiet), std::memory_order_relaxed);
  } else {
    hand.silence_run = 0;
    hand.silent_for_s.store(0.0, std::memory_order_relaxed);
  }
  if (hand.guard_latched) ++c.guard_latched_ticks;
}

bool HapticLoop::watch_instrument(Hand& hand) noexcept {
  // A device that does not know where it is: its instrument holds its last pose, and a force
  // computed there would push the hand towards a place it may no longer be. The same while the
  // clutch is held: the hand moves the handle, not the instrument.
  HandCounters& c = hand.counters;
  if (hand.clutch.held()) ++c.clutched_ticks;
  const bool untracked = !hand.lost && !hand.parts.haptic->device().state().tracked;
  if (untracked) {
    ++c.untracked_ticks;
    c.longest_untracked_ticks = std::max(c.longest_untracked_ticks, ++hand.untracked_run);
  } else {
    hand.untracked_run = 0;
  }
  hand.untracked_for_s.store(
      static_cast<double>(hand.untracked_run) * parts_.sim->haptic_period_ms() * 1e-3,
      std::memory_order_relaxed);
  return hand.clutch.held() || untracked;
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

double HapticLoop::stale_gain(std::uint64_t k, bool late) noexcept {
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
  return stale_gain_;
}

void HapticLoop::send_zero_locked(Hand& hand, const char* note_text) noexcept {
  note(note_text);
  try {
    hand.parts.haptic->send(hand.zeros);
  } catch (const std::exception&) {
    // Gone or unrecordable: the guard is latched either way, nothing more can be sent.
    hand.parts.haptic->guard().device_disconnected();
  }
  publish_output_locked(hand);
}

void HapticLoop::publish_output_locked(Hand& hand) noexcept {
  const std::vector<double>& output = hand.parts.haptic->last_output_N();
  double largest = 0.0;
  for (const double f : output)
    largest = std::max(largest, std::abs(f));
  hand.first_output_N.store(output.empty() ? 0.0 : output[0], std::memory_order_relaxed);
  hand.largest_output_N.store(largest, std::memory_order_release);
}

void HapticLoop::stop() noexcept {
  if (stopped_.exchange(true, std::memory_order_acq_rel)) return;
  for (const auto& h : hands_) {
    Hand& hand = *h;
    std::lock_guard lock(hand.device_mutex);
    // Latched first, so the zero goes out at once (a zero command alone is rate-limited down).
    hand.parts.haptic->guard().device_disconnected();
    if (!hand.lost) send_zero_locked(hand, hand.stop_note.c_str());
  }
}

bool HapticLoop::zero_if_stalled(devices::Nanoseconds now, devices::Nanoseconds limit) noexcept {
  const auto start = tick_start_ns_.load(std::memory_order_acquire);
  if (start < 0 || now.count() - start <= limit.count()) return false;
  if (stopped_.load(std::memory_order_acquire)) return false;
  bool zeroed = false;
  for (const auto& h : hands_)
    zeroed = zero_hand_if_stalled(*h) || zeroed;
  return zeroed;
}

bool HapticLoop::zero_hand_if_stalled(Hand& hand) noexcept {
  if (hand.zeroed_for_stall.load(std::memory_order_acquire)) return false;
  if (!hand.device_live.load(std::memory_order_acquire)) return false;
  // The zero that waits for nothing goes first, where the transport has one: past a tick stuck
  // in the device's write, and ahead of this thread's own write below, which a device that has
  // stopped taking reports would hold as well.
  const bool preempted = hand.parts.haptic->device().send_zero_preempting();
  if (preempted) {
    hand.first_output_N.store(0.0, std::memory_order_relaxed);
    hand.largest_output_N.store(0.0, std::memory_order_release);
  }
  std::unique_lock lock(hand.device_mutex, std::try_to_lock);
  if (!lock.owns_lock()) {
    // The tick holds the device. Without a preempting zero the next look tries again (the zero
    // then goes out when the tick lets go); with one, the tick finishes the job.
    if (!preempted) return false;
    hand.zeroed_for_stall.store(true, std::memory_order_release);
    hand.preempted.store(true, std::memory_order_release);
    return true;
  }
  if (hand.zeroed_for_stall.exchange(true, std::memory_order_acq_rel)) return preempted;
  return zero_for_stall_locked(hand) || preempted;
}

void HapticLoop::zero_now(std::size_t hand) noexcept {
  Hand& h = *hands_[hand];
  std::lock_guard lock(h.device_mutex);
  (void)zero_for_stall_locked(h);
}

bool HapticLoop::zero_for_stall_locked(Hand& hand) noexcept {
  if (stopped_.load(std::memory_order_acquire) || hand.lost) return false;
  // Latched first, so the zero goes out at once (a zero command alone is rate-limited down).
  hand.parts.haptic->guard().deadline_missed();
  send_zero_locked(hand, hand.watchdog_note.c_str());
  ++hand.counters.supervisor_zeros;
  return true;
}

double HapticLoop::silent_for_s(std::size_t hand) const {
  return hands_[hand]->silent_for_s.load(std::memory_order_relaxed);
}

std::uint64_t HapticLoop::guard_latches_now(std::size_t hand) const {
  return hands_[hand]->guard_latches_now.load(std::memory_order_relaxed);
}

double HapticLoop::untracked_for_s(std::size_t hand) const {
  return hands_[hand]->untracked_for_s.load(std::memory_order_relaxed);
}

const std::vector<double>& HapticLoop::command(std::size_t hand) const {
  return hands_[hand]->command;
}

bool HapticLoop::device_lost(std::size_t hand) const {
  return hands_[hand]->lost;
}

double HapticLoop::first_output_N() const {
  return hands_.front()->first_output_N.load(std::memory_order_relaxed);
}

double HapticLoop::largest_output_N() const {
  double largest = 0.0;
  for (const auto& h : hands_) {
    if (h->device_live.load(std::memory_order_acquire))
      largest = std::max(largest, h->largest_output_N.load(std::memory_order_acquire));
  }
  return largest;
}

}  // namespace bisturi::runtime
