// Rig calibrations (rig.json): capture::LoadRig.
#include "capture/rig.h"
#include "core/error.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    odvr::capture::LoadRig(odvr::fuzz::WriteInput(data, size, ".json"));
  } catch (const odvr::Error&) {
  }
  return 0;
}
