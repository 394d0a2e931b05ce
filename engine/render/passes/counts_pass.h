#pragma once
// A render's counts (RenderCounts): the per-sample lobes, cones, SG and triple products that the
// shading wrote, summed over the car's samples and the ground's — on the GPU (render_counts.comp)
// when the layers stay there, or on the CPU from the read-back counts, its reference. Internal to
// engine/render.
#include <cstdint>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/render/triple_product_internal.h"

namespace odvr::render {

class CountsPass {
 public:
  CountsPass();  // compiles render_counts.comp: needs a current OpenGL 4.5 context

  // Sums `counts` (a uvec4 per sample of samples_width × samples_height), the car's coverage
  // from `sample_car`'s alpha, each work group into its own slot; only those slots come back.
  // pixel_flags: adaptive supersampling's flags (`pixels` of them), counted where 1; null
  // otherwise (pixels_sampled_fully is then 0).
  detail::CountSums SumOnGpu(const gl::Buffer& counts, const gl::Buffer* pixel_flags, const gl::Texture& sample_car,
                             int samples_width, int samples_height, int pixels);

  // The same on the CPU: `sample_alpha` is the car's coverage per sample; sampled_fully per pixel.
  static detail::CountSums SumOnCpu(const std::vector<detail::PixelCounts>& counts,
                                    const std::vector<float>& sample_alpha,
                                    const std::vector<std::uint8_t>& sampled_fully);

  // RenderCounts' sums and means per car pixel from `sums`, and the lighting's SG and peak counts.
  static void Fill(const detail::CountSums& sums, const detail::PreparedLighting& lighting, RenderCounts* c);

 private:
  gl::Program program_{gl::NoCreate};
  gl::Buffer group_totals_{gl::NoCreate};
};

}  // namespace odvr::render
