#pragma once
// The stitcher's GPU path (capture internal): GLSL compute passes over the same lookup table as
// the CPU path. Camera frames go up as one RGBA8 texture array and are linearized in the shader
// through the same 256-entry sRGB table the CPU uses, at the same level (full or half
// resolution) with the same sums, so both paths sample identical values.
#include <cstdint>
#include <memory>
#include <opencv2/core/mat.hpp>
#include <vector>

#include "capture/rig.h"
#include "capture/stitcher.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::capture {

class GpuStitchPipeline {
 public:
  // Needs a current GL 4.5 context; uploads the lookup table once.
  GpuStitchPipeline(const Rig& rig, const StitchLut& lut);
  ~GpuStitchPipeline();
  GpuStitchPipeline(const GpuStitchPipeline&) = delete;
  GpuStitchPipeline& operator=(const GpuStitchPipeline&) = delete;

  // Warps, blends with `gains` (cameras with used[c] false are left out) and, with `fill`,
  // pull-push fills the unseen directions; reads the result back. Sets `report`'s ms_upload,
  // ms_gpu_passes and ms_readback.
  void Run(const std::vector<cv::Mat>& images, const std::vector<bool>& used, const std::vector<double>& gains,
           bool fill, sphere::EquirectImage* image, std::vector<std::uint8_t>* valid, StitchReport* report);

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace odvr::capture
