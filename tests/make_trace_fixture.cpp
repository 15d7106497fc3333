// Writes the recorded trace that CTest replays (tests/data/traces/sim_glove.btrace): 200 ms of
// the simulated glove and head tracker at 1 kHz, the glove unplugged at 100 ms and back at
// 120 ms, recorded through RecordingTransport in virtual time. Run it again only when a driver or
// a twin changes on purpose:  make_trace_fixture tests/data/traces/sim_glove.btrace

#include <exception>
#include <iostream>

#include "trace_fixture.h"

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: make_trace_fixture OUT\n";
    return 2;
  }
  try {
    bisturi::devices::testing::SimSessionOptions options;
    options.unplug_at = std::chrono::milliseconds(100);
    options.writer.max_chunk_records = 64;
    const std::size_t commands = bisturi::devices::testing::record_sim_session(argv[1], options);
    std::cout << "wrote " << argv[1] << ": " << commands << " force commands\n";
    return 0;
  } catch (const std::exception& e) {
    std::cerr << "make_trace_fixture: error: " << e.what() << "\n";
    return 1;
  }
}
