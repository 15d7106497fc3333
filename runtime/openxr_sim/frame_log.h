#pragma once
// What the simulated runtime saw, for tests that share nothing with it but the environment: one
// JSON object per line, appended to the file BISTURI_XR_SIM_LOG names, flushed at every line.

#include <cstdint>
#include <cstdio>
#include <string>

namespace bisturi::xrsim {

class FrameLog {
 public:
  FrameLog() = default;
  ~FrameLog();
  FrameLog(const FrameLog&) = delete;
  FrameLog& operator=(const FrameLog&) = delete;

  /// An empty path logs nothing.
  void open(const std::string& path);
  /// `fields`: the members of the object after "event", e.g. "\"state\":\"READY\"" (or empty).
  void write(const char* event, const std::string& fields = {});

 private:
  std::FILE* file_ = nullptr;
};

/// A JSON string literal (quotes and escapes).
std::string json_string(const std::string& text);
/// "[a,b,c]" with enough digits to compare poses exactly as floats.
std::string json_floats(const float* values, int count);

/// Writes RGBA8 rows as a PNG; false (and nothing written) when the file cannot be made.
bool write_png(const std::string& path, const std::uint8_t* rgba, std::uint32_t width,
               std::uint32_t height);

}  // namespace bisturi::xrsim
