#include "engine/lighting/lighting_builder.h"

#include <chrono>

namespace odvr::lighting {

LightingBuilder::LightingBuilder(LightingOptions options) : options_(options), transform_(options.transform) {
  options_.peaks.Check();
}

SgLighting LightingBuilder::Build(const sphere::EquirectImage& frame, LightingReport* report) {
  const auto start = std::chrono::steady_clock::now();
  LightingReport r;
  SgLighting model;
  if (options_.detect_peaks) {
    r.peak_detection = DetectPeaks(frame, options_.peaks);
    r.peaks_ms = r.peak_detection.ms;
    model = transform_.Run(r.peak_detection.residue, &r.transform);
    for (const auto& p : r.peak_detection.peaks) model.peaks.insert(model.peaks.end(), p.sgs.begin(), p.sgs.end());
    r.peak_detection.residue = {};
  } else {
    model = transform_.Run(frame, &r.transform);
  }
  r.total_ms = std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start).count();
  if (report) *report = std::move(r);
  return model;
}

}  // namespace odvr::lighting
