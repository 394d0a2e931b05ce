#pragma once
// RenderOptions::supersample > 1: the shaded samples' car and shadow layers filtered down to the
// output's (render_resolve.comp; its CPU reference is detail::ResolveSupersampled). Internal to
// engine/render.
#include "engine/gl/objects.h"
#include "engine/render/passes/render_targets.h"

namespace odvr::render {

class ResolvePass {
 public:
  ResolvePass();  // compiles render_resolve.comp: needs a current OpenGL 4.5 context

  // RenderTargets' shaded_car and shaded_shadow (fr.k× the output) into car_layer and
  // shadow_layer, by pixel_flags when fr.adaptive; issued, not waited for.
  void Run(const RenderFrame& fr, RenderTargets& targets);

 private:
  gl::Program program_{gl::NoCreate};
};

}  // namespace odvr::render
