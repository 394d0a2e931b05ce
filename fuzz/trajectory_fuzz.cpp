// Trajectories, as `play` and `export` read them: trajectory.json and TUM text
// (tracking::LoadTrajectoryJson, tracking::LoadTrajectoryTum). Each input is read both ways.
#include "core/error.h"
#include "fuzz/fuzz_input.h"
#include "tracking/evaluation.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  try {
    odvr::tracking::LoadTrajectoryJson(odvr::fuzz::WriteInput(data, size, ".json"));
  } catch (const odvr::Error&) {
  }
  try {
    odvr::tracking::LoadTrajectoryTum(odvr::fuzz::WriteInput(data, size, ".tum"), 30.0);
  } catch (const odvr::Error&) {
  }
  return 0;
}
