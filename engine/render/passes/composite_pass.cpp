#include "engine/render/passes/composite_pass.h"

#include <algorithm>
#include <cmath>
#include <glm/gtc/type_ptr.hpp>
#include <glm/vec2.hpp>
#include <string>

#include "core/error.h"
#include "engine/gl/shader_library.h"
#include "engine/sphere/equirect.h"

namespace odvr::render {
namespace {

// Bilinear look-up with GL's rules (texel centres at +0.5), longitude wrapping, latitude clamped.
glm::vec3 SampleEquirect(const sphere::EquirectImage& img, const glm::dvec3& d) {
  const glm::dvec2 px = sphere::EquirectPixel(d, img.width, img.height);
  const double x = px.x - 0.5, y = std::clamp(px.y - 0.5, 0.0, img.height - 1.0);
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  const auto at = [&](int c, int r) {
    c = ((c % img.width) + img.width) % img.width;
    r = std::clamp(r, 0, img.height - 1);
    const float* v = img.at(c, r);
    return glm::dvec3(v[0], v[1], v[2]);
  };
  return glm::vec3((1 - fy) * ((1 - fx) * at(x0, y0) + fx * at(x0 + 1, y0)) +
                   fy * ((1 - fx) * at(x0, y0 + 1) + fx * at(x0 + 1, y0 + 1)));
}

}  // namespace

CompositePass::CompositePass() : program_(gl::ShaderLibrary::Compute("render_composite.comp")) {}

void CompositePass::SetEquirect(const sphere::EquirectImage& equirect) {
  if (equirect.empty()) throw Error("background", "empty image");
  environment_ = equirect;
  is_image_ = false;
  texture_ = gl::Texture::Create2D(GL_RGB32F, equirect.width, equirect.height);
  texture_.Upload2D(GL_RGB, GL_FLOAT, equirect.rgb.data());
  texture_.SetWrap(GL_REPEAT, GL_CLAMP_TO_EDGE).SetFilter(GL_LINEAR, GL_LINEAR);
}

void CompositePass::SetImage(const sphere::EquirectImage& image) {
  if (image.empty()) throw Error("background", "empty image");
  image_ = image;
  is_image_ = true;
  texture_ = gl::Texture::Create2D(GL_RGB32F, image.width, image.height);
  texture_.Upload2D(GL_RGB, GL_FLOAT, image.rgb.data());
  texture_.SetFilter(GL_NEAREST, GL_NEAREST);
}

void CompositePass::CheckOutputSize(int w, int h) const {
  if (is_image_ && (image_.width != w || image_.height != h))
    throw Error("background", "image is " + std::to_string(image_.width) + "x" + std::to_string(image_.height) +
                                  ", the output " + std::to_string(w) + "x" + std::to_string(h));
}

void CompositePass::RunOnGpu(const RenderFrame& fr, const glm::dmat3& env_from_world, RenderTargets& targets) {
  const PinholeCamera& camera = fr.camera;
  const glm::mat3 wfc(camera.world_from_camera);
  gl::Program& cp = program_;
  const glm::mat3 background_efw(background_from_world_.value_or(env_from_world));
  cp.Set("uBackgroundIsImage", is_image_ ? 1 : 0)
      .Set("uCameraPosition", static_cast<float>(camera.position.x), static_cast<float>(camera.position.y),
           static_cast<float>(camera.position.z))
      .SetMat3("uWorldFromCamera", glm::value_ptr(wfc))
      .Set("uFocal", static_cast<float>(fr.f))
      .SetMat3("uEnvFromWorld", glm::value_ptr(background_efw));
  glProgramUniform2i(cp.id(), cp.Uniform("uSize"), fr.w, fr.h);
  if (!texture_) {  // no background: black
    static const float black[3] = {0, 0, 0};
    texture_ = gl::Texture::Create2D(GL_RGB32F, 1, 1);
    texture_.Upload2D(GL_RGB, GL_FLOAT, black);
  }
  texture_.BindUnit(0);
  targets.car_layer.BindImage(0, GL_READ_ONLY);
  targets.shadow_layer.BindImage(1, GL_READ_ONLY);
  targets.composite_layer.BindImage(2, GL_WRITE_ONLY);
  targets.background_layer.BindImage(3, GL_WRITE_ONLY);
  cp.Use().DispatchCovering(static_cast<unsigned>(fr.w), static_cast<unsigned>(fr.h));
  glMemoryBarrier(GL_ALL_BARRIER_BITS);
  gl::Finish();
}

void CompositePass::RunOnCpu(const RenderFrame& fr, const glm::dmat3& env_from_world, RenderResult* out) const {
  const int w = fr.w, h = fr.h;
  out->background = sphere::EquirectImage(w, h, 0.f);
  out->composite = sphere::EquirectImage(w, h, 0.f);
  const glm::dmat3 background_efw = background_from_world_.value_or(env_from_world);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * w + x;
      glm::vec3 bg(0);
      if (is_image_) {
        const float* b = image_.at(x, y);
        bg = glm::vec3(b[0], b[1], b[2]);
      } else if (!environment_.empty()) {
        bg = SampleEquirect(environment_, background_efw * fr.camera.Ray(x + 0.5, y + 0.5));
      }
      const float a = out->car_alpha[i];
      for (int c = 0; c < 3; ++c) {
        out->background.rgb[3 * i + c] = bg[c];
        out->composite.rgb[3 * i + c] = (1 - a) * bg[c] * out->shadow.rgb[3 * i + c] + a * out->car.rgb[3 * i + c];
      }
    }
}

}  // namespace odvr::render
