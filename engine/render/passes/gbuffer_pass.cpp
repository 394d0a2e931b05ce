#include "engine/render/passes/gbuffer_pass.h"

#include <algorithm>
#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>
#include <string>

#include "engine/gl/shader_library.h"

namespace odvr::render {

glm::mat4 ClipFromWorld(const PinholeCamera& camera, const scene::Bounds& bounds) {
  const double f = camera.focal_px();
  const int w = camera.width, h = camera.height;
  const glm::dmat3 camera_from_world = glm::transpose(camera.world_from_camera);
  double near = 0.01, far = 10;
  if (!bounds.empty()) {
    double dmin = 1e300, dmax = 0;
    for (int c = 0; c < 8; ++c) {
      const glm::dvec3 corner((c & 1) ? bounds.max.x : bounds.min.x, (c & 2) ? bounds.max.y : bounds.min.y,
                              (c & 4) ? bounds.max.z : bounds.min.z);
      const double z = (camera_from_world * (corner - camera.position)).z;
      dmin = std::min(dmin, z);
      dmax = std::max(dmax, z);
    }
    far = std::max(dmax * 1.01 + 0.01, 0.02);
    near = std::clamp(dmin * 0.99, far * 1e-6, far * 0.5);
    if (dmin <= 0) near = std::max(far * 1e-6, 1e-3);
  }
  glm::dmat4 clip(0.0);  // column-major: clip[col][row]
  clip[0][0] = 2 * f / w;
  clip[1][1] = 2 * f / h;
  clip[2][2] = (far + near) / (far - near);
  clip[3][2] = -2 * far * near / (far - near);
  clip[2][3] = 1;
  glm::dmat4 view(camera_from_world);
  view[3] = glm::dvec4(-(camera_from_world * camera.position), 1.0);
  return glm::mat4(clip * view);
}

GBufferPass::GBufferPass() : program_(gl::ShaderLibrary::Graphics("render_gbuffer.vert", "render_gbuffer.frag")) {}

void GBufferPass::Run(const RenderFrame& fr, const GpuModel& model, const GpuMaterials& materials,
                      RenderTargets& targets) {
  const PinholeCamera& camera = fr.shaded_camera;
  const glm::mat4 clip_from_world = ClipFromWorld(camera, fr.geometry ? model.bounds() : scene::Bounds{});
  gl::Framebuffer& framebuffer = targets.framebuffer;
  framebuffer.Bind();
  glViewport(0, 0, fr.sw, fr.sh);
  const float zero[4] = {0, 0, 0, 0};
  for (int i = 0; i < 4; ++i) glClearNamedFramebufferfv(framebuffer.id(), GL_COLOR, i, zero);
  const float one = 1.f;
  glClearNamedFramebufferfv(framebuffer.id(), GL_DEPTH, 0, &one);
  glEnable(GL_DEPTH_TEST);
  glDepthFunc(GL_LESS);
  glDisable(GL_CULL_FACE);
  glDisable(GL_BLEND);
  // The clip transform flips y (image rows grow downward), which turns CCW faces CW on screen.
  glFrontFace(GL_CW);
  program_.SetMat4("uClipFromWorld", glm::value_ptr(clip_from_world))
      .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
      .Set("uValidReflectionNormals", fr.options.valid_reflection_normals ? 1 : 0);
  if (fr.geometry)
    for (const auto& p : model.primitives()) Draw(model, p, materials);
  glFrontFace(GL_CCW);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  gl::Finish();
}

void GBufferPass::Draw(const GpuModel& model, const GpuModel::Primitive& p, const GpuMaterials& materials) {
  const auto index = static_cast<std::size_t>(p.material);
  const auto& m = model.materials()[index];
  const glm::vec3 emitted = materials.emission().at(index);
  const bool overridden = !materials.terms().at(index).from_gbuffer;
  gl::Program& gp = program_;
  gp.Set("uMaterialId", static_cast<float>(p.material + 1))
      .Set("uBaseColorFactor", m.base_color_factor.x, m.base_color_factor.y, m.base_color_factor.z,
           m.base_color_factor.w)
      .Set("uMetallicFactor", m.metallic_factor)
      .Set("uRoughnessFactor", m.roughness_factor)
      .Set("uNormalScale", m.normal_scale)
      .Set("uEmission", emitted.x, emitted.y, emitted.z)
      .Set("uTransmission", m.transmission)
      .Set("uAlphaCutoff", m.alpha_mode == scene::PbrMaterial::AlphaMode::kMask && !overridden ? m.alpha_cutoff : -1.f);
  // Texture units: base colour and emission sRGB, the others linear (render_gbuffer.frag); the
  // white texel for a texture the material lacks.
  const scene::TextureRef* refs[4] = {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture,
                                      &m.emissive_texture};
  for (int k = 0; k < 4; ++k) {
    const auto& r = *refs[k];
    const std::string s = std::to_string(k);
    // An override's surface has no normal map (its terms read no other texture).
    const bool use = r.valid() && !(overridden && k == 2);
    glProgramUniform2i(gp.id(), gp.Uniform(("uTexUse[" + s + "]").c_str()), use ? 1 : 0, r.texcoord);
    gp.Set(("uTexOffsetScale[" + s + "]").c_str(), r.offset.x, r.offset.y, r.scale.x, r.scale.y)
        .Set(("uTexRotation[" + s + "]").c_str(), r.rotation);
    model.Texture(r.valid() ? r.image : -1, k == 0 || k == 3).BindUnit(static_cast<GLuint>(k));
  }
  gp.Use();
  p.vao.Bind();
  glDrawElements(GL_TRIANGLES, p.index_count, GL_UNSIGNED_INT, nullptr);
}

}  // namespace odvr::render
