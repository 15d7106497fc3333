#include "fuzz_harness.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  return bisturi::fuzz::run_one(data, size, bisturi::MeshFormat::Stl);
}
