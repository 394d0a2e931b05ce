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
  int peak_grid_width = 1024;
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

 private:
  LightingOptions options_;
  ResidualTransform transform_;
};

}  // namespace odvr::lighting
