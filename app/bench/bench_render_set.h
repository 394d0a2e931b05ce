#pragma once
// `odvr bench render --set DIR`: the renderer's default configuration over a generalization set
// of Cycles references (tools/blender/render_reference.py --generalization-set: one folder per
// model, each image a map × material × ground), reported as distributions: the median and 90th
// percentile of the car's error and bias by map, model, material, ground and silhouette region.
#include <string>
#include <vector>

#include "app/bench/bench_common.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

struct BenchRenderSetOptions {
  std::string set_dir;             // the generalization set: DIR/<model>/set.json and its images
  std::string envs_dir;            // where the images' maps are (default: ../shared/data/env)
  bool ground_bounce = true;       // the catcher images: the maps' lower half = the catcher seen from the car
  render::RenderOptions switches;  // what every render starts from
  std::string out_dir = kBenchOutDir;
  std::string images_dir;         // non-empty: each image's car layer as EXR there
  std::vector<std::string> only;  // non-empty: only the images whose name (model/image) contains one
  // > 0: each image also rendered by the Monte-Carlo baseline at this many samples per pixel
  // (shadow rays against the triangles with mc_exact, else through the voxels), reported beside
  // the SG rows: what is the model's error and what is the lighting's and visibility's.
  int mc_samples = 0;
  bool mc_exact = false;
  unsigned mc_seed = 1;
  // Rewrite render_set.md and .png from out_dir's render_set.tsv; set_dir still gives the notes of
  // what the set left out, and mc_samples / mc_exact must be the run's.
  bool report_only = false;
};

// Renders and scores every image of the set; writes render_set.md, .tsv and .png in out_dir.
// Returns the exit code.
int RunBenchRenderSet(const BenchRenderSetOptions& o);

}  // namespace odvr::app
