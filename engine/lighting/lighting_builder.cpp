#include "engine/lighting/lighting_builder.h"

#include <chrono>
#include <cmath>

#include "engine/core/error.h"
#include "engine/lighting/residual_transform_gpu.h"
#include "engine/sphere/resample.h"

namespace odvr::lighting {

LightingBuilder::LightingBuilder(LightingOptions options) : options_(options), transform_(options.transform) {
  options_.peaks.Check();
  if (options_.peak_grid_width < 64) throw Error("peak grid width", "must be at least 64");
}

SgLighting LightingBuilder::Build(const sphere::EquirectImage& frame, LightingReport* report,
                                  ResidualTransformGpu* gpu) {
  const auto start = std::chrono::steady_clock::now();
  LightingReport r;
  SgLighting model;
  sphere::EquirectImage small;
  const sphere::EquirectImage* source = &frame;
  if (frame.width > options_.peak_grid_width) {
    const int w = options_.peak_grid_width;
    const int h = static_cast<int>(std::lround(static_cast<double>(frame.height) * w / frame.width));
    small = sphere::ResampleArea(frame, w, h);
    source = &small;
  }
  r.resample_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (options_.detect_peaks) {
    // The resampled frame is ours: it becomes the residue without a copy.
    r.peak_detection =
        source == &small ? DetectPeaks(std::move(small), options_.peaks) : DetectPeaks(frame, options_.peaks);
    r.peaks_ms = r.peak_detection.ms;
    model =
        gpu ? gpu->Run(r.peak_detection.residue, &r.transform) : transform_.Run(r.peak_detection.residue, &r.transform);
    for (const auto& p : r.peak_detection.peaks) model.peaks.insert(model.peaks.end(), p.sgs.begin(), p.sgs.end());
    r.peak_detection.residue = {};
  } else {
    model = gpu ? gpu->Run(*source, &r.transform) : transform_.Run(*source, &r.transform);
  }
  r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (report) *report = std::move(r);
  return model;
}

}  // namespace odvr::lighting
