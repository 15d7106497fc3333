#pragma once
// Replays a recorded session in virtual time: the trace's configuration holds the scene (its TOML
// text) and the force guard's settings, so the replay rebuilds the same solids and runs the same
// SessionSim on the haptic states the recorded reports give, tick by tick (a tick is a force
// command record, or a "tick" note while the haptic device was lost), each tick's command coming
// from the step the live session used (as its StepSchedule says, with the ticks per step changing
// where a
// {"tissue_rate": ...} note says, or as a late-tick note says). It checks that
//  - every force command the session computed equals the recorded one, bit for bit;
//  - the final state hash of the soft bodies equals the one the session stored in its closing
//    note ({"session_end": {"state_hash": ...}});
//  - the drivers and the force guard write the recorded output reports byte for byte
//    (devices::replay_trace over the same file).

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "bisturi/devices/trace/trace_replay.h"

namespace bisturi::runtime {

struct ForceMismatch {
  std::uint64_t tick = 0;
  std::int64_t time_ns = 0;
  std::vector<double> expected_N;
  std::vector<double> actual_N;
};

struct SessionReplayResult {
  [[nodiscard]] bool passed() const {
    return !trace_error && force_mismatches == 0 && expected_state_hash &&
           *expected_state_hash == state_hash && (!expected_ticks || *expected_ticks == ticks) &&
           devices.passed();
  }

  std::string scene;
  std::uint32_t tissue_threads = 1;  ///< the recorded thread count the steps ran on
  std::uint64_t ticks = 0;
  std::uint64_t force_commands = 0;
  std::uint64_t force_mismatches = 0;
  std::optional<ForceMismatch> first_mismatch;
  std::uint64_t state_hash = 0;
  std::optional<std::uint64_t> expected_state_hash;  ///< nullopt: the trace has no closing note
  std::optional<std::uint64_t> expected_ticks;
  /// The first bad chunk (everything before it was replayed).
  std::optional<devices::TraceCorruptError> trace_error;
  devices::TraceReplayResult devices;
  double seconds = 0.0;  ///< wall time the replay took
};

/// Throws devices::TraceError when the file is not a trace or its configuration holds no session,
/// SceneFileError when the stored scene no longer builds.
SessionReplayResult replay_session(const std::filesystem::path& trace);

}  // namespace bisturi::runtime
