#pragma once
// What one TripleProductRenderer::Render shares between its passes: its arguments and the sizes
// and modes they and the options give, fixed before the first pass. Internal to engine/render.
#include <cstddef>
#include <glm/vec2.hpp>

#include "engine/render/pinhole_camera.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::render {

struct RenderFrame {
  explicit RenderFrame(const RenderOptions& o) : options(o) {}
  const RenderOptions& options;
  ShadeDevice device = ShadeDevice::kGpu;
  PinholeCamera camera;         // the output's
  PinholeCamera shaded_camera;  // the G-buffer's and the shading's: k× the output's size
  int w = 0, h = 0;             // the output
  int k = 1;                    // RenderOptions::supersample
  int sw = 0, sh = 0;           // the shaded samples: k × w by k × h
  int bw = 0, bh = 0;           // shading_rate 2's 2×2 blocks: a block cut by an odd edge is shaded whole
  // Without the model: nothing voxelized, drawn or occluding, so the composite is the background.
  bool geometry = false;
  bool monte_carlo = false;
  // Adaptive supersampling (RenderOptions::supersample_contrast) in the SG shader only.
  bool adaptive = false;
  // RenderOptions::shading_rate 2: a pixel of each 2×2 block, then every pixel of the blocks
  // that need it, the rest filled.
  bool half_rate = false;
  double f = 0, sf = 0;  // focal lengths in pixels: the output's, the shaded samples'
  glm::dvec2 ground_centre{0};
  std::size_t pixels = 0, samples = 0;  // w × h, sw × sh

  // The frame of a render of `camera` (checked) with `options`; `geometry`: the model is drawn.
  static RenderFrame Make(const RenderOptions& options, const PinholeCamera& camera, ShadeDevice device, bool geometry,
                          const glm::dvec2& ground_centre);
};

}  // namespace odvr::render
