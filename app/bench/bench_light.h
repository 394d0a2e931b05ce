#pragma once
// `odvr bench light`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"
#include "engine/lighting/residual_transform.h"

namespace odvr::app {

struct BenchLightOptions {
  std::vector<std::string> maps;
  std::vector<int> widths = {1024, 2048};
  int max_levels = 6;
  int only_levels = 0;  // 0: every level count up to max_levels
  bool skip_peaks = false;
  int repeats = 3;
  // Timed runs continue past `repeats` until this much time has passed (at most kMaxRuns): with
  // three runs, SH 8's median, the same work on every map, read 0.75–1.22 ms across the maps.
  double min_time_ms = 100;
  bool gpu = false;
  // Before each GPU row, untimed calls for this long (WarmUp).
  double gpu_warm_up_ms = 200;
  bool least_squares = true;
  // SH projects an area-resampled copy of the same frame the SG model gets, at this width, and
  // its time includes that resampling. From a 2048-wide frame, SH 8 and 16 projected at 256 wide
  // are within 1 % of their errors projected at full width on sky, park, sunset and bridge; at
  // 128 the diffuse error grows 3-12 % (bridge: 3x).
  int sh_width = 256;
  std::string out_dir = kBenchOutDir;
  bool report_only = false;
  lighting::ResidualTransformOptions transform;  // the tuning flags (AddTransformTuning)
};

// Runs the bench: its table, TSV and plot in the options' out_dir; returns the exit code.
int RunBenchLight(BenchLightOptions o);

// Declares the options on `sub` (`odvr bench light`); returns the function that runs them.
CommandFn AddBenchLight(CLI::App* sub);

}  // namespace odvr::app
