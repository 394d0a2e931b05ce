#pragma once
// `odvr bench decode`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"

namespace odvr::app {

struct BenchDecodeOptions {
  std::vector<std::string> clips;  // default: the demo and ../shared/data/video360's videos
  long max_frames = 300;
  std::string out_dir = kBenchOutDir;
};

// Runs the bench: its table, TSV and plot in the options' out_dir; returns the exit code.
int RunBenchDecode(const BenchDecodeOptions& options);

// Declares the options on `sub` (`odvr bench decode`); returns the function that runs them.
CommandFn AddBenchDecode(CLI::App* sub);

}  // namespace odvr::app
