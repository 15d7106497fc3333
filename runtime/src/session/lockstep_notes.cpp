// The session's lockstep trace notes (see lockstep_notes.h).

#include "lockstep_notes.h"

#include <array>
#include <nlohmann/json.hpp>

namespace bisturi::runtime {

namespace {

/// The two unsigned fields `a` and `b` of the object under `key`, when the text is such a note.
std::optional<std::array<std::uint64_t, 2>> two_fields(const std::string& text, const char* key,
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

std::string late_tick_note(std::uint64_t tick, std::uint64_t step) {
  return nlohmann::json{{"late_tick", {{"tick", tick}, {"step", step}}}}.dump();
}

std::optional<LateTick> parse_late_tick_note(const std::string& text) {
  const auto f = two_fields(text, "late_tick", "tick", "step");
  if (!f) return std::nullopt;
  return LateTick{(*f)[0], (*f)[1]};
}

std::string tissue_rate_note(std::uint64_t tick, std::uint32_t ticks_per_step) {
  return nlohmann::json{{"tissue_rate", {{"tick", tick}, {"ticks_per_step", ticks_per_step}}}}
      .dump();
}

std::optional<TissueRateChange> parse_tissue_rate_note(const std::string& text) {
  const auto f = two_fields(text, "tissue_rate", "tick", "ticks_per_step");
  if (!f || (*f)[1] < 1 || (*f)[1] > 1000) return std::nullopt;
  return TissueRateChange{(*f)[0], static_cast<std::uint32_t>((*f)[1])};
}

std::string dropped_step_note(std::uint64_t tick, std::uint64_t step) {
  return nlohmann::json{{"dropped_step", {{"tick", tick}, {"step", step}}}}.dump();
}

std::optional<DroppedStep> parse_dropped_step_note(const std::string& text) {
  const auto f = two_fields(text, "dropped_step", "tick", "step");
  if (!f) return std::nullopt;
  return DroppedStep{(*f)[0], (*f)[1]};
}

}  // namespace bisturi::runtime
