#include "bisturi/runtime/session/headset_report.h"

#include <nlohmann/json.hpp>

namespace bisturi::runtime {

std::string to_json(const HeadsetReport& r) {
  nlohmann::json states = nlohmann::json::array();
  for (const HeadsetStateChange& s : r.states)
    states.push_back({{"state", s.state}, {"time_s", s.time_s}});
  const nlohmann::json j = {{"sink", r.sink},
                            {"runtime", r.runtime},
                            {"reference_space", r.reference_space},
                            {"swapchain_format", r.swapchain_format},
                            {"eye_width", r.eye_width},
                            {"eye_height", r.eye_height},
                            {"display_period_ms", r.display_period_ms},
                            {"min_display_period_ms", r.min_display_period_ms},
                            {"max_display_period_ms", r.max_display_period_ms},
                            {"display_hz", r.display_hz},
                            {"frames_begun", r.frames_begun},
                            {"frames_submitted", r.frames_submitted},
                            {"frames_not_rendered", r.frames_not_rendered},
                            {"frames_without_views", r.frames_without_views},
                            {"dropped_frames", r.dropped_frames},
                            {"invalid_view_locations", r.invalid_view_locations},
                            {"states", states},
                            {"sessions_lost", r.sessions_lost},
                            {"sessions_recreated", r.sessions_recreated},
                            {"ticks_without_display", r.ticks_without_display},
                            {"display_stalls", r.display_stalls},
                            {"display_timeout_ms", r.display_timeout_ms},
                            {"shared_device", r.shared_device},
                            {"frames_crossed_cpu", r.frames_crossed_cpu},
                            {"frames_read_back", r.frames_read_back},
                            {"fov_rad", {{"left_eye", r.fov[0]}, {"right_eye", r.fov[1]}}},
                            {"stop_reason", r.stop_reason},
                            {"note", r.note}};
  return j.dump();
}

}  // namespace bisturi::runtime
