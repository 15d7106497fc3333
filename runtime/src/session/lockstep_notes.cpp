// The session's lockstep trace notes (see lockstep_notes.h).

#include "lockstep_notes.h"

#include <algorithm>
#include <array>
#include <cstdio>
#include <nlohmann/json.hpp>

namespace bisturi::runtime {

namespace {

/// The two unsigned fields `a` and `b` of the object under `key`, when the text is such a note.
std::optional<std::array<std::uint64_t, 2>> two_fields(std::string_view text, const char* key,
                                                       const char* a, const char* b) {
  const nlohmann::json j = nlohmann::json::parse(text, nullptr, false);
  if (j.is_discarded() || !j.is_object() || !j.contains(key)) return std::nullopt;
  const nlohmann::json& o = j[key];
  if (!o.is_object() || !o.contains(a) || !o.contains(b) || !o[a].is_number_unsigned() ||
      !o[b].is_number_unsigned())
    return std::nullopt;
  return std::array<std::uint64_t, 2>{o[a].get<std::uint64_t>(), o[b].get<std::uint64_t>()};
}

}  // namespace

/// {"key":{"a":va,"b":vb}} with a and b in the order given (the notes give them sorted, as a
/// JSON library writing them from a map would).
NoteText format_note(const char* key, const char* a, std::uint64_t va, const char* b,
                     std::uint64_t vb) {
  NoteText note;
  const int n =
      std::snprintf(note.text_.data(), note.text_.size(), "{\"%s\":{\"%s\":%llu,\"%s\":%llu}}", key,
                    a, static_cast<unsigned long long>(va), b, static_cast<unsigned long long>(vb));
  note.size_ =
      n < 0 ? 0 : std::min<std::size_t>(static_cast<std::size_t>(n), note.text_.size() - 1);
  return note;
}

NoteText late_tick_note(std::uint64_t tick, std::uint64_t step) {
  return format_note("late_tick", "step", step, "tick", tick);
}

std::optional<LateTick> parse_late_tick_note(std::string_view text) {
  const auto f = two_fields(text, "late_tick", "tick", "step");
  if (!f) return std::nullopt;
  return LateTick{(*f)[0], (*f)[1]};
}

NoteText tissue_rate_note(std::uint64_t tick, std::uint32_t ticks_per_step) {
  return format_note("tissue_rate", "tick", tick, "ticks_per_step", ticks_per_step);
}

std::optional<TissueRateChange> parse_tissue_rate_note(std::string_view text) {
  const auto f = two_fields(text, "tissue_rate", "tick", "ticks_per_step");
  if (!f || (*f)[1] < 1 || (*f)[1] > 1000) return std::nullopt;
  return TissueRateChange{(*f)[0], static_cast<std::uint32_t>((*f)[1])};
}

NoteText dropped_step_note(std::uint64_t tick, std::uint64_t step) {
  return format_note("dropped_step", "step", step, "tick", tick);
}

std::optional<DroppedStep> parse_dropped_step_note(std::string_view text) {
  const auto f = two_fields(text, "dropped_step", "tick", "step");
  if (!f) return std::nullopt;
  return DroppedStep{(*f)[0], (*f)[1]};
}

NoteText blood_hold_note(std::uint64_t tick, bool held) {
  return format_note("blood_hold", "held", held ? 1 : 0, "tick", tick);
}

std::optional<BloodHold> parse_blood_hold_note(std::string_view text) {
  const auto f = two_fields(text, "blood_hold", "tick", "held");
  if (!f || (*f)[1] > 1) return std::nullopt;
  return BloodHold{(*f)[0], (*f)[1] == 1};
}

std::string hand_note(std::string_view what, std::size_t hand) {
  std::string text(what);
  if (hand > 0) {
    text += ' ';
    text += std::to_string(hand);
  }
  return text;
}

std::optional<std::size_t> parse_hand_note(std::string_view text, std::string_view what) {
  if (text.substr(0, what.size()) != what) return std::nullopt;
  text.remove_prefix(what.size());
  if (text.empty()) return 0;
  if (text.front() != ' ' || text.size() < 2) return std::nullopt;
  std::size_t hand = 0;
  for (const char c : text.substr(1)) {
    if (c < '0' || c > '9' || hand > 1000) return std::nullopt;
    hand = hand * 10 + static_cast<std::size_t>(c - '0');
  }
  return hand;
}

}  // namespace bisturi::runtime
