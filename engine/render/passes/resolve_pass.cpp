#include "engine/render/passes/resolve_pass.h"

#include <vector>

#include "engine/gl/shader_library.h"

namespace odvr::render {

ResolvePass::ResolvePass() : program_(gl::ShaderLibrary::Compute("render_resolve.comp")) {}

void ResolvePass::Run(const RenderFrame& fr, RenderTargets& targets) {
  const int w = fr.w, h = fr.h, k = fr.k;
  gl::Program& rp = program_;
  const std::vector<float> weights = detail::SupersampleWeights(k);
  glProgramUniform2i(rp.id(), rp.Uniform("uSize"), w, h);
  glProgramUniform2i(rp.id(), rp.Uniform("uShadedSize"), fr.sw, fr.sh);
  rp.Set("uFactor", k).Set("uAdaptive", fr.adaptive ? 1 : 0);
  if (fr.adaptive) targets.pixel_flags.BindBase(GL_SHADER_STORAGE_BUFFER, 9);
  glProgramUniform1fv(rp.id(), rp.Uniform("uWeights"), static_cast<GLsizei>(weights.size()), weights.data());
  targets.shaded_car.BindImage(0, GL_READ_ONLY);
  targets.shaded_shadow.BindImage(1, GL_READ_ONLY);
  targets.car_layer.BindImage(2, GL_WRITE_ONLY);
  targets.shadow_layer.BindImage(3, GL_WRITE_ONLY);
  rp.Use().DispatchCovering(static_cast<unsigned>(w), static_cast<unsigned>(h));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
}

}  // namespace odvr::render
