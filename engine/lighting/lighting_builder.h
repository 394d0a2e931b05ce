#pragma once
// Frame → lighting model: peaks out first, then the residual transform of what is left.
#include <string>

#include "engine/lighting/peak_detector.h"
#include "engine/lighting/residual_transform.h"

namespace odvr::lighting {

struct LightingOptions {
  ResidualTransformOptions transform;
  PeakDetectorOptions peaks;
  bool detect_peaks = true;
  // Peaks are found on the frame area-resampled to at most this width (energy is preserved; a
  // 1024-wide pixel is 0.35°, below a sun disc's 0.5°), and the transform starts from there.
  // Without peaks (on the CPU) the transform takes a frame it can box-average evenly to its
  // finest grid as it is: the same grids, one pass less.
  int peak_grid_width = 1024;
  // The detector box-averages the frame to the transform's finest working grid in its own pass
  // (same result: tests/engine/lighting/lighting_builder_test.cpp); false: the transform
  // resamples the residue itself, as before.
  bool fuse_coarse_grid = true;
};

struct LightingReport {
  TransformReport transform;
  PeakDetection peak_detection;  // its residue is released after use
  double resample_ms = 0;
  double peaks_ms = 0;
  double total_ms = 0;
};

class ResidualTransformGpu;

class LightingBuilder {
 public:
  explicit LightingBuilder(LightingOptions options = {});
  // With `gpu` (its context current), the residual transform runs there; peaks stay on the CPU.
  SgLighting Build(const sphere::EquirectImage& frame, LightingReport* report = nullptr,
                   ResidualTransformGpu* gpu = nullptr);
  ResidualTransform& transform() { return transform_; }
  const LightingOptions& options() const { return options_; }
  // The box factor from a width×height frame to the transform's finest grid, when the detector
  // can produce that grid (1: it cannot, the transform resamples).
  int FusedFactor(int width, int height) const;

 private:
  LightingOptions options_;
  ResidualTransform transform_;
  sphere::EquirectImage peak_grid_;    // the detector's grid of a wider frame, reused every frame
  sphere::EquirectImage coarse_grid_;  // storage for the detector's coarse grid, handed back every frame
};

}  // namespace odvr::lighting
