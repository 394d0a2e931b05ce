#include "engine/render/panorama_renderer.h"

#include <glm/gtc/type_ptr.hpp>
#include <glm/matrix.hpp>

#include "core/error.h"
#include "engine/gl/shader_library.h"

namespace odvr::render {

PanoramaRenderer::PanoramaRenderer() : program_(gl::ShaderLibrary::Graphics("panorama.vert", "panorama.frag")) {}

void PanoramaRenderer::EnsureTexture(GLenum internal_format, int width, int height) {
  if (width <= 0 || height <= 0) throw Error("panorama", "empty frame");
  if (!texture_ || texture_.width() != width || texture_.height() != height ||
      texture_.internal_format() != internal_format) {
    texture_ = gl::Texture::Create2D(internal_format, width, height);
    // Longitude wraps (the seam is continuous); latitude clamps at the poles.
    texture_.SetWrap(GL_REPEAT, GL_CLAMP_TO_EDGE).SetFilter(GL_LINEAR, GL_LINEAR);
  }
}

void PanoramaRenderer::UploadSrgb8(int width, int height, const std::uint8_t* rgb) {
  EnsureTexture(GL_SRGB8, width, height);
  texture_.Upload2D(GL_RGB, GL_UNSIGNED_BYTE, rgb);
}

void PanoramaRenderer::UploadLinear(int width, int height, const float* rgb) {
  EnsureTexture(GL_RGB16F, width, height);
  texture_.Upload2D(GL_RGB, GL_FLOAT, rgb);
}

void PanoramaRenderer::Draw(const glm::mat4& view, const glm::mat4& projection, float exposure, bool encode_srgb) {
  if (!texture_) return;
  glm::mat4 rotation = view;
  rotation[3] = glm::vec4(0, 0, 0, 1);  // the viewer stays at the centre
  const glm::mat4 world_from_clip = glm::inverse(projection * rotation);
  // Rows are uploaded top row first, so texture v = 0 is the zenith, as equirectPixel expects.
  program_.SetMat4("uWorldFromClip", glm::value_ptr(world_from_clip))
      .Set("uExposure", exposure)
      .Set("uEncodeSrgb", encode_srgb ? 1 : 0);
  program_.Use();
  texture_.BindUnit(0);
  empty_vao_.Bind();
  glDisable(GL_DEPTH_TEST);
  glDrawArrays(GL_TRIANGLES, 0, 3);
}

}  // namespace odvr::render
