#include <algorithm>

#include "bisturi/runtime/session/session.h"

namespace bisturi::runtime {

MissedAroundCut missed_around_first_cut(const SessionReport& report) {
  MissedAroundCut out;
  const std::uint64_t cut =
      report.first_cut_tick < 0
          ? report.ticks
          : std::min<std::uint64_t>(static_cast<std::uint64_t>(report.first_cut_tick),
                                    report.ticks);
  for (const std::uint64_t tick : report.missed_deadline_ticks)
    ++(tick < cut ? out.before : out.after);
  // Past the room kept for them: counted after the cut (the last of the session).
  out.after +=
      report.missed_deadlines -
      std::min<std::uint64_t>(report.missed_deadlines, report.missed_deadline_ticks.size());
  out.ticks_before = cut;
  out.ticks_after = report.ticks - cut;
  return out;
}

}  // namespace bisturi::runtime
