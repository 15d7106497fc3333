#include "fuzz_volume_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return bisturi::fuzz::run_volume(data, size,
                                   [](std::span<const std::byte> d, const std::string& n) {
                                     return bisturi::read_nrrd_from_memory(d, n);
                                   });
}
