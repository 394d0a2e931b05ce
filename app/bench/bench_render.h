#pragma once
// `odvr bench render`: its options, the program, and its flags on a command line.
#include <CLI/CLI.hpp>
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "app/flags/command_flags.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

struct BenchRenderOptions {
  std::string reference_dir = "media/reference";
  std::string street_dir;         // default: ../shared/data/street_a (frame 10), when present
  std::vector<std::string> only;  // reference names to run (default: all)
  std::vector<int> levels = {2, 3, 5};
  std::vector<int> cones = {1, 7, 19};
  std::vector<int> voxels = {64, 128, 256};
  std::vector<int> mc_samples = {4, 16, 64, 256};
  std::vector<int> mc_voxels = {128};  // the Monte-Carlo rows' voxel resolutions
  unsigned mc_seed = 1;
  bool mc_exact = false;  // also Monte-Carlo rows with ray-traced visibility ("mc-exact")
  // Each k > 1: the default configuration's SG row, the sweep's finest configuration (the most
  // levels, cones and voxels swept; at the largest contrast) and the Monte-Carlo rows again with k×k
  // shaded samples per pixel (RenderOptions::supersample), MC at samples/k² each (the same rays per
  // pixel).
  std::vector<int> supersample = {1, 2};
  // And for each k > 1, one SG row per contrast (RenderOptions::supersample_contrast; 0: every
  // sample of every pixel).
  std::vector<double> supersample_contrast = {0, render::RenderOptions{}.supersample_contrast};
  std::string images_dir;     // non-empty: each scored row's car layer and shadow ratio as EXR there
  bool lobe_modes = true;     // also the four warp × cosine modes at the default configuration
  bool hd_row = true;         // a 1280×720 row (shade ms)
  bool ground_bounce = true;  // the maps' lower half = Cycles' catcher seen from the car
  // What every row starts from: RenderOptions' defaults but for AddRenderSwitches' flags, for A/B
  // runs (the shading rate applies to the SG rows of one sample per pixel).
  render::RenderOptions switches;
  std::string out_dir = kBenchOutDir;
  bool report_only = false;
};

// Runs the bench: its table, TSV and plot in the options' out_dir; returns the exit code.
int RunBenchRender(BenchRenderOptions o);

// Declares the options on `sub` (`odvr bench render`); returns the function that runs them.
CommandFn AddBenchRender(CLI::App* sub);

}  // namespace odvr::app
