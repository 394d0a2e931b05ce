#include "engine/render/passes/render_targets.h"

#include <string>

#include "core/error.h"

namespace odvr::render {

void RenderTargets::Ensure(const RenderFrame& fr) {
  GLint max_size = 0;
  glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
  if (fr.sw > max_size || fr.sh > max_size)
    throw Error("render supersample", std::to_string(fr.k) + "x" + std::to_string(fr.k) + " samples of " +
                                          std::to_string(fr.w) + "x" + std::to_string(fr.h) + " make " +
                                          std::to_string(fr.sw) + "x" + std::to_string(fr.sh) +
                                          ", beyond the GPU's textures (" + std::to_string(max_size) + ")");
  const int w = fr.sw, h = fr.sh, out_w = fr.w, out_h = fr.h;
  if (w == fb_width_ && h == fb_height_ && out_w == out_width_ && out_h == out_height_) return;
  fb_width_ = w;
  fb_height_ = h;
  out_width_ = out_w;
  out_height_ = out_h;
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

detail::GBuffer RenderTargets::ReadGBuffer() const {
  detail::GBuffer g;
  g.width = fb_width_;
  g.height = fb_height_;
  g.position = g_position.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.normal = g_normal.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.base = g_base.Read<float>(GL_RGBA, GL_FLOAT, 4);
  g.emission = g_emission.Read<float>(GL_RGBA, GL_FLOAT, 4);
  return g;
}

}  // namespace odvr::render
