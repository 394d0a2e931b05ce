#pragma once
// `odvr bench reconstruct`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <filesystem>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"

namespace odvr::app {

struct BenchReconstructOptions {
  std::string dataset =
      (std::filesystem::path(ODVR_SOURCE_DIR) / ".." / "shared" / "data" / "street_a").lexically_normal().string();
  long frames = 0;  // 0: every frame of the dataset
  bool no_colmap = false, colmap_only = false, report_only = false, keep_workspace = false;
  bool equirect = false;  // one 360° camera: bench_reconstruct_equirect.cpp
  int crf = 23, track_width = 1024;
  long clip_frames = 60;
  long long_frames = 600;
  std::string colmap = "colmap";
  std::string out_dir = kBenchOutDir;
};

// Runs the bench: its table, TSV and plot in the options' out_dir; returns the exit code.
int RunBenchReconstruct(const BenchReconstructOptions& o);

// Declares the options on `sub` (`odvr bench reconstruct`); returns the function that runs them.
CommandFn AddBenchReconstruct(CLI::App* sub);

}  // namespace odvr::app
