// Linked into every fuzz target as an object (libFuzzer only looks for LLVMFuzzerInitialize as a
// weak symbol, which would not pull it from a static library).
#include <spdlog/spdlog.h>

// odvr's own warnings (clamped pixels and the like) would flood the fuzzer's output.
extern "C" int LLVMFuzzerInitialize(int*, char***) {
  spdlog::set_level(spdlog::level::off);
  return 0;
}
