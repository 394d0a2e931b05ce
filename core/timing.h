#pragma once
// Elapsed time for the stage timings every command reports, on the steady clock (never the wall
// clock, which jumps).
#include <chrono>

namespace odvr {

using SteadyClock = std::chrono::steady_clock;

inline double MsSince(SteadyClock::time_point start) {
  return std::chrono::duration<double, std::milli>(SteadyClock::now() - start).count();
}

inline double SecondsSince(SteadyClock::time_point start) {
  return std::chrono::duration<double>(SteadyClock::now() - start).count();
}

}  // namespace odvr
