#include "engine/render/passes/render_frame.h"

namespace odvr::render {

RenderFrame RenderFrame::Make(const RenderOptions& options, const PinholeCamera& camera, ShadeDevice device,
                              bool geometry, const glm::dvec2& ground_centre) {
  camera.Check();
  RenderFrame fr(options);
  fr.device = device;
  fr.camera = camera;
  fr.w = camera.width;
  fr.h = camera.height;
  fr.k = options.supersample;
  fr.shaded_camera = camera;
  fr.shaded_camera.width = fr.k * fr.w;
  fr.shaded_camera.height = fr.k * fr.h;
  fr.sw = fr.shaded_camera.width;
  fr.sh = fr.shaded_camera.height;
  fr.bw = (fr.w + 1) / 2;
  fr.bh = (fr.h + 1) / 2;
  fr.geometry = geometry;
  fr.monte_carlo = options.monte_carlo_samples > 0;
  fr.adaptive = fr.k > 1 && options.supersample_contrast > 0 && !fr.monte_carlo;
  fr.half_rate = options.shading_rate == 2;
  fr.f = camera.focal_px();
  fr.sf = fr.shaded_camera.focal_px();
  fr.ground_centre = ground_centre;
  fr.pixels = static_cast<std::size_t>(fr.w) * fr.h;
  fr.samples = static_cast<std::size_t>(fr.sw) * fr.sh;
  return fr;
}

}  // namespace odvr::render
