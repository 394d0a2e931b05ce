#pragma once
// `odvr bench player`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"
#include "app/player/player.h"

namespace odvr::app {

struct BenchPlayerOptions {
  std::string size = "1280x720";
  int frames = 8;
  std::string drive = "W:2s,A:1s";
  std::string out = std::string(kBenchOutDir) + "/player.md";
  int levels = 4, voxels = 64;
  int shading_rate = PlayerOptions{}.shading_rate;
  bool live = false;
  CLI::Option* size_option = nullptr;  // on a command line: whether --size was given
};

// Runs the bench: its page at `out`; returns the exit code.
int RunBenchPlayer(const BenchPlayerOptions& b);

// Declares the options on `sub` (`odvr bench player`); returns the function that runs them.
CommandFn AddBenchPlayer(CLI::App* sub);

}  // namespace odvr::app
