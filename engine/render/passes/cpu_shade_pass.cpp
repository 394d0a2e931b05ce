#include "engine/render/passes/cpu_shade_pass.h"

#include <cstdint>

namespace odvr::render {

namespace detail {

std::vector<std::uint8_t> HalfRateShaded(const std::vector<std::uint8_t>& block_flags, int w, int h) {
  std::vector<std::uint8_t> shaded(static_cast<std::size_t>(w) * static_cast<std::size_t>(h));
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x)
      shaded[static_cast<std::size_t>(y) * w + x] =
          block_flags[static_cast<std::size_t>(y / 2) * ((w + 1) / 2) + x / 2] || (x % 2 == 1 && y % 2 == 1) ? 1 : 0;
  return shaded;
}

}  // namespace detail

void ShadeOnCpu(const RenderFrame& fr, const ShadeScene& scene, const detail::GBuffer& g, RenderResult* out,
                std::vector<detail::PixelCounts>* sample_counts_out, std::vector<float>* sample_alpha) {
  const RenderOptions& o = fr.options;
  const int w = fr.w, h = fr.h, k = fr.k, sw = fr.sw, sh = fr.sh;
  std::vector<detail::PixelCounts>& sample_counts = *sample_counts_out;
  detail::ReferenceInputs in;
  in.gbuffer = &g;
  in.camera = fr.shaded_camera;
  in.materials = &scene.materials.terms();
  in.lighting = &scene.lighting.prepared();
  in.bins = &scene.lighting.bins();
  in.grid = fr.geometry ? scene.voxels.cpu_grid() : nullptr;
  in.bvh = fr.geometry && o.exact_peak_shadows ? scene.model.bvh() : nullptr;
  in.model = &scene.model;
  in.options = o;
  in.ground_centre = fr.ground_centre;
  if (k > 1) {
    RenderResult shaded;
    detail::ShadeReference(in, &shaded, &sample_counts);
    if (fr.adaptive) {
      // Every sample is shaded here; the ones the GPU would not shade are left out of the
      // result, the counts and the coverage alike.
      out->sampled_fully = detail::FlagPixels(g, shaded, k, w, h, static_cast<float>(o.supersample_contrast));
      for (int y = 0; y < sh; ++y)
        for (int x = 0; x < sw; ++x) {
          const std::size_t s = static_cast<std::size_t>(y) * sw + x;
          if (!out->sampled_fully[static_cast<std::size_t>(y / k) * w + x / k] && (x % k != k / 2 || y % k != k / 2)) {
            sample_counts[s] = {};
            shaded.car_alpha[s] = 0;
          }
        }
      detail::ResolveSupersampled(shaded, k, w, h, out, &out->sampled_fully);
    } else {
      out->sampled_fully.assign(fr.pixels, 1);
      detail::ResolveSupersampled(shaded, k, w, h, out);
    }
    *sample_alpha = std::move(shaded.car_alpha);
  } else if (fr.half_rate) {
    // Every pixel is shaded here; the flags pick the blocks the GPU shades whole, and the other
    // blocks' pixels are filled as render_fill.comp fills them, out of the counts.
    detail::ShadeReference(in, out, &sample_counts);
    const std::vector<std::uint8_t> block =
        detail::FlagPixels(g, *out, 2, fr.bw, fr.bh, static_cast<float>(o.supersample_contrast), true);
    detail::FillHalfRate(block, out);
    out->sampled_fully = detail::HalfRateShaded(block, w, h);
    for (std::size_t i = 0; i < fr.pixels; ++i)
      if (!out->sampled_fully[i]) sample_counts[i] = {};
  } else {
    detail::ShadeReference(in, out, &sample_counts);
  }
}

}  // namespace odvr::render
