#pragma once
// The Monte-Carlo baseline's shading pass (render_mc.comp, RenderOptions::monte_carlo_samples):
// the environment map sampled by its luminance, the BRDF evaluated per sample, visibility by a
// voxel-wide cone or by exact rays against the BVH. What the SG pass is measured against at equal
// time. Internal to engine/render.
#include "engine/gl/objects.h"
#include "engine/render/passes/shade_inputs.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::render {

class MonteCarloShadePass {
 public:
  MonteCarloShadePass();  // compiles render_mc.comp: needs a current OpenGL 4.5 context

  // The map it samples: its texels and their sampling tables (the rows' and the columns' CDFs).
  void SetEnvironment(const sphere::EquirectImage& equirect);
  bool has_environment() const { return static_cast<bool>(environment_texture_); }

  // Shades fr's samples into RenderTargets' shaded layers and counts; issued, not waited for.
  void Run(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets);

 private:
  gl::Program program_{gl::NoCreate};
  sphere::EquirectImage environment_;
  gl::Texture environment_texture_{gl::NoCreate};
  gl::Buffer env_row_cdf_{gl::NoCreate}, env_col_cdf_{gl::NoCreate}, env_texel_prob_{gl::NoCreate};
};

}  // namespace odvr::render
