#pragma once
// The notes a live session writes into its trace so that its replay pairs the same tissue steps
// with the same haptic ticks (tissue_thread.h, step_schedule.h). Each is one JSON object with one
// key, written just before the tick's force command. The haptic tick writes them: each is made in
// a fixed buffer (NoteText), never on the heap.

#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

namespace bisturi::runtime {

/// A note's text in a buffer of its own (two 20-digit numbers and the keys fit).
class NoteText {
 public:
  [[nodiscard]] std::string_view view() const { return {text_.data(), size_}; }
  operator std::string_view() const { return view(); }  // NOLINT: a note is its text
  [[nodiscard]] std::string str() const { return std::string(view()); }

 private:
  friend NoteText format_note(const char* key, const char* a, std::uint64_t va, const char* b,
                              std::uint64_t vb);
  std::array<char, 96> text_{};
  std::size_t size_ = 0;
};

/// A late tick: {"late_tick": {"tick": k, "step": j}}: tick k used step j, the newest finished
/// one, because its due step was not finished (step 0: none had, the command was zero).
NoteText late_tick_note(std::uint64_t tick, std::uint64_t step);
struct LateTick {
  std::uint64_t tick = 0;
  std::uint64_t step = 0;
};
/// The late tick a note's text holds, if it is one.
std::optional<LateTick> parse_late_tick_note(std::string_view text);

/// A change of the ticks per tissue step at hand-over tick k:
/// {"tissue_rate": {"tick": k, "ticks_per_step": n}}.
NoteText tissue_rate_note(std::uint64_t tick, std::uint32_t ticks_per_step);
struct TissueRateChange {
  std::uint64_t tick = 0;
  std::uint32_t ticks_per_step = 1;
};
/// The change a note's text holds, if it is one (ticks_per_step 1 to 1000).
std::optional<TissueRateChange> parse_tissue_rate_note(std::string_view text);

/// A hand-over the tissue could not queue (its ring full): {"dropped_step": {"tick": k,
/// "step": j}}: step j was never taken, and the steps after it take its number.
NoteText dropped_step_note(std::uint64_t tick, std::uint64_t step);
struct DroppedStep {
  std::uint64_t tick = 0;
  std::uint64_t step = 0;
};
std::optional<DroppedStep> parse_dropped_step_note(std::string_view text);

/// The blood's clock stopped (held 1) or going again (held 0) from the step handed over at tick
/// k on: {"blood_hold": {"held": h, "tick": k}} (SessionSim::tick's blood_held).
NoteText blood_hold_note(std::uint64_t tick, bool held);
struct BloodHold {
  std::uint64_t tick = 0;
  bool held = false;
};
std::optional<BloodHold> parse_blood_hold_note(std::string_view text);

/// A zero a hand's device is about to get ("haptic_stop" at the end, "watchdog_zero" from the
/// supervisor): the note names the hand after the first ("watchdog_zero 1"), so a one-handed
/// trace reads as it always has. Made once, at the loop's start.
std::string hand_note(std::string_view what, std::size_t hand);
/// The hand a note's text names for `what` (0 for the plain word), if it is that note.
std::optional<std::size_t> parse_hand_note(std::string_view text, std::string_view what);

}  // namespace bisturi::runtime
