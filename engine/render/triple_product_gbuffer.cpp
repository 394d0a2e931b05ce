// TripleProductRenderer's first passes: a render's Frame and checks, the stage timestamps, the
// voxelization and the G-buffer (triple_product_impl.h).
#include <algorithm>
#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>
#include <string>

#include "core/error.h"
#include "core/timing.h"
#include "engine/render/triple_product_impl.h"

namespace odvr::render {

TripleProductRenderer::Impl::Frame TripleProductRenderer::Impl::MakeFrame(const RenderOptions& options,
                                                                          const PinholeCamera& camera,
                                                                          ShadeDevice device, bool draw_model) const {
  camera.Check();
  const int w = camera.width, h = camera.height;
  if (background_is_image && (background_image.width != w || background_image.height != h))
    throw Error("background", "image is " + std::to_string(background_image.width) + "x" +
                                  std::to_string(background_image.height) + ", the output " + std::to_string(w) + "x" +
                                  std::to_string(h));
  const bool monte_carlo = options.monte_carlo_samples > 0;
  if (monte_carlo && device != ShadeDevice::kGpu)
    throw Error("render", "the Monte-Carlo baseline runs on the GPU only");
  if (monte_carlo && !mc_environment) throw Error("render", "the Monte-Carlo baseline needs SetEnvironment");
  Frame fr(options);
  fr.device = device;
  fr.camera = camera;
  fr.w = w;
  fr.h = h;
  fr.k = options.supersample;
  fr.shaded_camera = camera;
  fr.shaded_camera.width = fr.k * w;
  fr.shaded_camera.height = fr.k * h;
  fr.sw = fr.shaded_camera.width;
  fr.sh = fr.shaded_camera.height;
  fr.bw = (w + 1) / 2;
  fr.bh = (h + 1) / 2;
  fr.geometry = has_geometry && draw_model;
  fr.monte_carlo = monte_carlo;
  fr.adaptive = fr.k > 1 && options.supersample_contrast > 0 && !monte_carlo;
  fr.half_rate = options.shading_rate == 2;
  fr.gpu_stages = device == ShadeDevice::kGpu;
  fr.f = camera.focal_px();
  fr.sf = fr.shaded_camera.focal_px();
  fr.ground_centre = glm::dvec2(bounds.empty() ? 0.0 : bounds.center().x, bounds.empty() ? 0.0 : bounds.center().z);
  fr.pixels = static_cast<std::size_t>(w) * h;
  fr.samples = static_cast<std::size_t>(fr.sw) * fr.sh;
  return fr;
}

void TripleProductRenderer::Impl::Stamp(const Frame& fr, int stage) {
  if (!fr.gpu_stages) return;
  if (stage_queries[0] == 0)
    glCreateQueries(GL_TIMESTAMP, static_cast<GLsizei>(stage_queries.size()), stage_queries.data());
  glQueryCounter(stage_queries[static_cast<std::size_t>(stage)], GL_TIMESTAMP);
}

void TripleProductRenderer::Impl::Voxelize(const Frame& fr, RenderTimings* ms) {
  const auto t0 = SteadyClock::now();
  if (fr.geometry) {
    if (fr.device == ShadeDevice::kGpu) {
      voxelizer->Voxelize(triangle_buffer, triangles.size() / 3);
      gl::Finish();
    } else {
      cpu_grid = std::make_unique<visibility::VoxelGrid>(spec);
      cpu_grid->Voxelize(triangles);
      cpu_grid->BuildMips();
    }
  }
  ms->voxelize = MsSince(t0);
}

void TripleProductRenderer::Impl::EnsureTargets(int w, int h, int out_w, int out_h) {
  if (w == fb_width && h == fb_height && out_w == out_width && out_h == out_height) return;
  fb_width = w;
  fb_height = h;
  out_width = out_w;
  out_height = out_h;
  const auto rgba32 = [&](int tw, int th) {
    gl::Texture t = gl::Texture::Create2D(GL_RGBA32F, tw, th);
    t.SetFilter(GL_NEAREST, GL_NEAREST);
    return t;
  };
  g_position = rgba32(w, h);
  g_normal = rgba32(w, h);
  g_base = rgba32(w, h);
  g_emission = rgba32(w, h);
  car_layer = rgba32(out_w, out_h);
  shadow_layer = rgba32(out_w, out_h);
  composite_layer = rgba32(out_w, out_h);
  background_layer = rgba32(out_w, out_h);
  const bool supersampled = w != out_w || h != out_h;
  shaded_car = supersampled ? rgba32(w, h) : gl::Texture(gl::NoCreate);
  shaded_shadow = supersampled ? rgba32(w, h) : gl::Texture(gl::NoCreate);
  pixel_flags = gl::Buffer(gl::NoCreate);
  flagged_list = gl::Buffer(gl::NoCreate);
  if (supersampled) {
    pixel_flags = gl::Buffer();
    pixel_flags.Allocate(static_cast<std::size_t>(out_w) * out_h * 4);
    flagged_list = gl::Buffer();
    flagged_list.Allocate(4 + static_cast<std::size_t>(out_w) * out_h * 4);
  }
  g_depth = gl::Texture::Create2D(GL_DEPTH_COMPONENT32F, w, h);
  framebuffer = gl::Framebuffer();
  framebuffer.AttachColor(g_position, 0)
      .AttachColor(g_normal, 1)
      .AttachColor(g_base, 2)
      .AttachColor(g_emission, 3)
      .AttachDepth(g_depth);
  const GLenum draw[4] = {GL_COLOR_ATTACHMENT0, GL_COLOR_ATTACHMENT1, GL_COLOR_ATTACHMENT2, GL_COLOR_ATTACHMENT3};
  glNamedFramebufferDrawBuffers(framebuffer.id(), 4, draw);
  framebuffer.CheckComplete();
  counts = gl::Buffer();
  counts.Allocate(static_cast<std::size_t>(w) * h * 16);
}

void TripleProductRenderer::Impl::RasterizeGBuffer(const Frame& fr, RenderTimings* ms) {
  const auto t0 = SteadyClock::now();
  const int w = fr.w, h = fr.h, k = fr.k, sw = fr.sw, sh = fr.sh;
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (sw > max_size || sh > max_size)
    throw Error("render supersample", std::to_string(k) + "x" + std::to_string(k) + " samples of " + std::to_string(w) +
                                          "x" + std::to_string(h) + " make " + std::to_string(sw) + "x" +
                                          std::to_string(sh) + ", beyond the GPU's textures (" +
                                          std::to_string(max_size) + ")");
  EnsureTargets(sw, sh, w, h);
  const glm::mat4 clip_from_world = ClipFromWorld(fr);

  framebuffer.Bind();
  glViewport(0, 0, sw, sh);
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
  const PinholeCamera& camera = fr.camera;
  gl::Program& gp = gbuffer_program;
  gp.SetMat4("uClipFromWorld", glm::value_ptr(clip_from_world))
      .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
      .Set("uValidReflectionNormals", fr.options.valid_reflection_normals ? 1 : 0);
  if (fr.geometry)
    for (auto& p : primitives) DrawGBufferPrimitive(gp, p);
  glFrontFace(GL_CCW);
  glBindFramebuffer(GL_FRAMEBUFFER, 0);
  gl::Finish();
  ms->gbuffer = MsSince(t0);
}

glm::mat4 TripleProductRenderer::Impl::ClipFromWorld(const Frame& fr) const {
  const PinholeCamera& camera = fr.camera;
  const double sf = fr.sf;
  const int sw = fr.sw, sh = fr.sh;
  const glm::dmat3 camera_from_world = glm::transpose(camera.world_from_camera);
  double near = 0.01, far = 10;
  if (fr.geometry) {
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
  clip[0][0] = 2 * sf / sw;
  clip[1][1] = 2 * sf / sh;
  clip[2][2] = (far + near) / (far - near);
  clip[3][2] = -2 * far * near / (far - near);
  clip[2][3] = 1;
  glm::dmat4 view(camera_from_world);
  view[3] = glm::dvec4(-(camera_from_world * camera.position), 1.0);
  return glm::mat4(clip * view);
}

void TripleProductRenderer::Impl::DrawGBufferPrimitive(gl::Program& gp, Primitive& p) {
  const auto& m = materials[static_cast<std::size_t>(p.material)];
  const glm::vec3 emitted = emission.at(static_cast<std::size_t>(p.material));
  gp.Set("uMaterialId", static_cast<float>(p.material + 1))
      .Set("uBaseColorFactor", m.base_color_factor.x, m.base_color_factor.y, m.base_color_factor.z,
           m.base_color_factor.w)
      .Set("uMetallicFactor", m.metallic_factor)
      .Set("uRoughnessFactor", m.roughness_factor)
      .Set("uNormalScale", m.normal_scale)
      .Set("uEmission", emitted.x, emitted.y, emitted.z)
      .Set("uTransmission", m.transmission)
      .Set("uAlphaCutoff", m.alpha_mode == scene::PbrMaterial::AlphaMode::kMask ? m.alpha_cutoff : -1.f);
  // Texture units: base colour and emission sRGB, the others linear (render_gbuffer.frag).
  const scene::TextureRef* refs[4] = {&m.base_color_texture, &m.metallic_roughness_texture, &m.normal_texture,
                                      &m.emissive_texture};
  for (int k = 0; k < 4; ++k) {
    const auto& r = *refs[k];
    const std::string s = std::to_string(k);
    glProgramUniform2i(gp.id(), gp.Uniform(("uTexUse[" + s + "]").c_str()), r.valid() ? 1 : 0, r.texcoord);
    gp.Set(("uTexOffsetScale[" + s + "]").c_str(), r.offset.x, r.offset.y, r.scale.x, r.scale.y)
        .Set(("uTexRotation[" + s + "]").c_str(), r.rotation);
    if (r.valid()) {
      const auto it = textures.find({r.image, k == 0 || k == 3});
      if (it != textures.end()) {
        it->second.BindUnit(static_cast<GLuint>(k));
        continue;
      }
    }
    white.BindUnit(static_cast<GLuint>(k));
  }
  gp.Use();
  p.vao.Bind();
  glDrawElements(GL_TRIANGLES, p.index_count, GL_UNSIGNED_INT, nullptr);
}

}  // namespace odvr::render
