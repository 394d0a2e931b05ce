#include "engine/lighting/lighting_builder.h"

#include <chrono>
#include <cmath>

#include "core/error.h"
#include "engine/lighting/residual_transform_gpu.h"

namespace odvr::lighting {

LightingBuilder::LightingBuilder(LightingOptions options) : options_(options), transform_(options.transform) {
  options_.peaks.Check();
  if (options_.peak_grid_width < 64) throw Error("peak grid width", "must be at least 64");
}

int LightingBuilder::FusedFactor(int width, int height) const {
  if (!options_.fuse_coarse_grid) return 1;
  const int levels = options_.transform.levels;
  const auto [cw, ch] = WorkingGrid(options_.transform, levels - 1, width, height);
  if (cw >= width || width % cw || height % ch || width / cw != height / ch) return 1;
  // Starting from the coarse grid must give every level the grid it gets from the frame.
  for (int s = 0; s < levels; ++s)
    if (WorkingGrid(options_.transform, s, cw, ch) != WorkingGrid(options_.transform, s, width, height)) return 1;
  return width / cw;
}

SgLighting LightingBuilder::Build(const sphere::EquirectImage& frame, LightingReport* report,
                                  ResidualTransformGpu* gpu) {
  const auto start = std::chrono::steady_clock::now();
  LightingReport r;
  SgLighting model;
  sphere::EquirectImage small;
  const sphere::EquirectImage* source = &frame;
  int grid_w = frame.width, grid_h = frame.height, frame_factor = 1;
  if (frame.width > options_.peak_grid_width) {
    grid_w = options_.peak_grid_width;
    grid_h = static_cast<int>(std::lround(static_cast<double>(frame.height) * grid_w / frame.width));
    // An integer factor is where ResampleArea box-averages; the detector can do that in its pass.
    if (frame.width % grid_w == 0 && frame.height % grid_h == 0 && frame.width / grid_w == frame.height / grid_h)
      frame_factor = frame.width / grid_w;
  }
  const int factor = options_.detect_peaks ? FusedFactor(grid_w, grid_h) : 1;
  // Without peaks, a frame that box-averages evenly to the transform's finest grid goes to the
  // transform whole: it derives the same grids from it, and its box pass runs on its threads
  // where a resample to the peak grid first would run on one.
  const int fused = FusedFactor(grid_w, grid_h);
  const bool direct = !options_.detect_peaks && !gpu && frame_factor > 1 && fused > 1;
  // Without peaks, the GPU gets the frame resampled here, on our threads, straight to the
  // transform's finest grid, as the peaks path hands it the detector's coarse grid: uploading the
  // peak grid and resampling it on one thread took several times the transform itself.
  const bool gpu_grid = !options_.detect_peaks && gpu && fused > 1;
  if (gpu_grid || (frame.width > options_.peak_grid_width && !direct && (factor == 1 || frame_factor == 1))) {
    small.Reshape(gpu_grid ? grid_w / fused : grid_w, gpu_grid ? grid_h / fused : grid_h);
    ResampleToGrid(frame, &small, transform_.pool());
    source = &small;
    frame_factor = 1;
  }
  r.resample_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (options_.detect_peaks) {
    // When the transform's finest grid divides the frame evenly, the detector box-averages the
    // frame to it in its own pass (corrected where the peaks took light out): the transform
    // starts there and derives the same grids, and the full-resolution residue is neither
    // copied nor read again (a frame wider than the peak grid by an integer factor is
    // box-averaged to it in that pass too). Otherwise the resampled frame, ours, becomes the residue.
    if (factor > 1)
      r.peak_detection = DetectPeaksToCoarseGrid(*source, factor, options_.peaks, frame_factor, &peak_grid_,
                                                 transform_.pool(), &coarse_grid_);
    else
      r.peak_detection =
          source == &small ? DetectPeaks(std::move(small), options_.peaks) : DetectPeaks(frame, options_.peaks);
    r.peaks_ms = r.peak_detection.ms;
    sphere::EquirectImage& start_grid = factor > 1 ? r.peak_detection.coarse : r.peak_detection.residue;
    model = gpu ? gpu->Run(start_grid, &r.transform) : transform_.Run(std::move(start_grid), &r.transform);
    for (const auto& p : r.peak_detection.peaks) model.peaks.insert(model.peaks.end(), p.sgs.begin(), p.sgs.end());
    r.peak_detection.residue = {};
    // The transform handed back the previous frame's grid for it: the next frame's coarse grid.
    coarse_grid_ = std::move(r.peak_detection.coarse);
    r.peak_detection.coarse = {};
  } else {
    model = gpu ? gpu->Run(*source, &r.transform) : transform_.Run(*source, &r.transform);
  }
  r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (report) *report = std::move(r);
  return model;
}

}  // namespace odvr::lighting
