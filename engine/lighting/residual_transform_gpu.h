#pragma once
// The GPU path of the multiscale residual transform (seed §4.4.3, Algorithms 1–3; DESIGN.md §4):
// the same algorithm and the same decisions as ResidualTransform (residual_transform.h), with
// the work in GLSL compute shaders. Per level, as in the seed, two passes: the projection (one
// work group per SRBF over its precomputed pixel list, a shared-memory reduction) and the
// reconstruction with the residue update (one invocation per pixel over its SRBF list); a level's
// refitting sweeps run on its amplitudes between the two (lighting_gram.comp, LevelGram). The
// frame is uploaded once (or read from a texture the caller already has), area-resampled to the
// working grids, and the coarser levels evaluated on each grid (or, with exact_reconstruction
// off, their reconstruction magnified) on the GPU. Every level is queued without a read-back in
// between: after each, lighting_gate.comp applies the stop and rejection rules on the GPU and
// closes a gate that turns the later levels' passes into no-ops; then one read brings back each
// level's sums (mean |residue|, RMS, kept count) and amplitudes, and the CPU replays the same
// rules on them to pick the levels it keeps. Three waits for the GPU in all (the frame's sums,
// the levels, the coarse correction) where there were three per level. The overlap lists come
// from the CPU's BuildLevelTables, built once per grid size and kept on the GPU as storage
// buffers.
#include <chrono>
#include <map>
#include <memory>
#include <tuple>
#include <vector>

#include "core/parallel.h"
#include "engine/gl/objects.h"
#include "engine/lighting/residual_transform.h"

namespace odvr::lighting {

class ResidualTransformGpu {
 public:
  // Needs a current OpenGL 4.5 context (compiles its shaders); throws odvr::Error otherwise
  // and for invalid options. Every call must be made with that context current.
  explicit ResidualTransformGpu(ResidualTransformOptions options = {});
  ~ResidualTransformGpu();
  ResidualTransformGpu(const ResidualTransformGpu&) = delete;
  ResidualTransformGpu& operator=(const ResidualTransformGpu&) = delete;

  // As ResidualTransform::Run; report->device is "gpu".
  SgLighting Run(const sphere::EquirectImage& input, TransformReport* report = nullptr);
  // A frame already on the GPU: a 2D texture of linear RGB, texel row 0 the top row (as
  // PanoramaRenderer uploads it). Level 0 of it is read; its filter settings do not matter.
  SgLighting Run(const gl::Texture& frame, TransformReport* report = nullptr);

  const ResidualTransformOptions& options() const { return options_; }

 private:
  struct Grid;
  struct Tables;
  SgLighting RunOnTexture(GLuint frame, int input_width, int input_height, std::chrono::steady_clock::time_point start,
                          TransformReport* report);
  struct Readback;
  void PrepareGrids(int input_width, int input_height);
  void ResampleIntoGrids(GLuint frame, int input_width, int input_height);
  int QueueLevel(int s, const glm::vec3& constant, float keep, double abs_limit, int* recon_index);
  void RefitSweeps(const Tables& t, const gl::Buffer& mu, int s);
  // What the queued levels left for the CPU, in one transfer: the slots' sums, each level's kept
  // SRBFs, how many levels the gate let run, their GPU times, and their amplitudes (results_ up
  // to `end`, level s's from mu_offset[s]).
  Readback ReadQueued(std::vector<std::size_t> mu_offset, std::size_t end);
  // The stop and keep rules again, on the same sums and with the same comparisons as the gate:
  // the kept levels into *model, each level's line and the stop reason into *report. Returns
  // whether the residue fell below the threshold; *leftover is what every kept level left (for
  // the coarse correction), on grids_[*leftover_grid].
  bool PickLevels(const Readback& r, double abs_limit, SgLighting* model, TransformReport* report,
                  const gl::Buffer** leftover, int* leftover_grid);
  // `projection`: the by-SRBF lists too (only a level's own grid projects).
  const Tables& TablesFor(int level, int width, int height, bool projection);
  // Sums of `image` over the sphere into slot `slot` of totals_ (no readback).
  void Sums(const gl::Buffer& image, const Grid& grid, int slot);
  void Project(const Tables& tables, const gl::Buffer& residue, const gl::Buffer& mu, bool accumulate,
               float step = 1.f);
  // out = base + sign·Σ μ G (tables == nullptr: nothing added); with `residue`, also grid's image
  // − out there. See lighting_reconstruct.comp.
  void Reconstruct(const Tables* tables, const gl::Buffer& mu, const gl::Buffer& base, const gl::Buffer& out,
                   float sign, const Grid& grid, const gl::Buffer* residue);
  // ResidualTransformOptions::coarse_correction, as the CPU path does it: `leftover` is what every
  // level left, on grids_[leftover_grid] (refitted in place when that is the upper level's grid).
  void CorrectCoarserLevels(const gl::Buffer& leftover, int leftover_grid, float keep, SgLighting* model);

  ResidualTransformOptions options_;
  std::unique_ptr<ThreadPool> pool_;  // builds the overlap lists
  // resample_: between grids (the pyramid, the coarse correction's restriction); both weigh rows
  // by solid angle, as sphere::ResampleArea does.
  gl::Program resample_texture_{gl::NoCreate}, resample_{gl::NoCreate}, upsample_{gl::NoCreate}, stats_{gl::NoCreate},
      stats_total_{gl::NoCreate}, project_{gl::NoCreate}, reconstruct_{gl::NoCreate}, keep_{gl::NoCreate},
      gram_{gl::NoCreate}, gate_program_{gl::NoCreate};
  std::map<std::tuple<int, int, int>, std::unique_ptr<Tables>> tables_;
  std::vector<std::unique_ptr<Grid>> grids_;  // per level, for the last input size
  int grids_input_width_ = 0, grids_input_height_ = 0;
  // Scratch images (vec4 per pixel) sized for the finest grid, and the per-level state.
  gl::Buffer recon_[2], correction_, row_sums_, totals_, flags_, counters_, gate_, mu_[2];
  gl::Buffer sweep_mu_[2];  // a level's refits on its amplitudes: its first projection, the next μ
  // Per level, on its grid: the residue entering it and what it leaves (the coarse correction
  // needs the last kept level's, which the levels queued after it must not overwrite), and its
  // amplitudes.
  std::vector<gl::Buffer> level_residue_, level_remaining_, level_mu_;
  gl::Buffer results_;                 // totals, flags and every level's amplitudes, copied together for one read
  std::vector<GLuint> level_queries_;  // GL timestamps at each level's start and the last one's end
  gl::Texture upload_{gl::NoCreate};   // the frame of Run(EquirectImage), reused while the size holds
};

}  // namespace odvr::lighting
