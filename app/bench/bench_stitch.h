#pragma once
// `odvr bench stitch`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"

namespace odvr::app {

struct BenchStitchOptions {
  std::string dataset =
      (std::filesystem::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "street_a").lexically_normal().string();
  std::vector<int> frames = {0, 8, 16, 24, 32};
  int width = 1024, height = 512;
  int repeats = 3;
  double scene_distance_m = 0;
  bool gpu = false;
  std::string out_dir = kBenchOutDir;
};

// Runs the bench: its table, TSV and plot in the options' out_dir; returns the exit code.
int RunBenchStitch(const BenchStitchOptions& o);

// Declares the options on `sub` (`odvr bench stitch`); returns the function that runs them.
CommandFn AddBenchStitch(CLI::App* sub);

}  // namespace odvr::app
