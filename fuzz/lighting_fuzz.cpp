// Lighting models (`odvr light --out`, read by `render --lighting`): lighting::SgLighting::Load.
#include "core/error.h"
#include "engine/lighting/sg_lighting.h"
#include "fuzz/fuzz_input.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    odvr::lighting::SgLighting::Load(odvr::fuzz::WriteInput(data, size, ".json"));
  } catch (const odvr::Error&) {
  }
  return 0;
}
