#pragma once
// Draws the equirectangular frame around the viewer (the player's background): a full-screen
// pass that looks each pixel's ray up in the panorama. Rotation only: the viewer sits at the
// panorama's centre.
#include <cstdint>
#include <glm/mat4x4.hpp>

#include "engine/gl/objects.h"

namespace odvr::render {

class PanoramaRenderer {
 public:
  PanoramaRenderer();  // compiles its shaders: needs a current GL context

  // 8-bit sRGB RGB rows, top row first (as decoded); linearized by the texture format.
  void UploadSrgb8(int width, int height, const std::uint8_t* rgb);
  // Linear float RGB rows, top row first.
  void UploadLinear(int width, int height, const float* rgb);
  bool has_frame() const { return static_cast<bool>(texture_); }

  // `view` is the world-to-camera rotation (OpenGL convention), `projection` a perspective.
  // Draws into the bound framebuffer's viewport; sRGB-encodes the output when `encode_srgb`.
  void Draw(const glm::mat4& view, const glm::mat4& projection, float exposure = 1.0f, bool encode_srgb = true);

 private:
  void EnsureTexture(GLenum internal_format, int width, int height);
  gl::Program program_{gl::NoCreate};
  gl::Texture texture_{gl::NoCreate};
  gl::VertexArray empty_vao_;
};

}  // namespace odvr::render
