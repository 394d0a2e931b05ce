#pragma once
// The last pass: the background (the environment map seen through the camera, or a given image)
// with the car over it and the shadow ratio applied to it where the car leaves it uncovered,
// composite = (1 − α) · background · shadow + α · car, on the GPU (render_composite.comp) or the
// CPU, which is its reference. Internal to engine/render.
#include <optional>

#include <glm/mat3x3.hpp>

#include "engine/gl/objects.h"
#include "engine/render/passes/render_targets.h"
#include "engine/sphere/equirect_image.h"

namespace odvr::render {

class CompositePass {
 public:
  CompositePass();  // compiles render_composite.comp: needs a current OpenGL 4.5 context

  // The background: an equirectangular map seen through the camera, turned by the lighting's
  // env_from_world unless SetRotation gave it its own; or an image of the output's size.
  void SetEquirect(const sphere::EquirectImage& equirect);
  void SetImage(const sphere::EquirectImage& image);
  void SetRotation(const std::optional<glm::dmat3>& background_from_world) {
    background_from_world_ = background_from_world;
  }
  // Throws odvr::Error when the background is an image of another size than w × h.
  void CheckOutputSize(int w, int h) const;

  // RenderTargets' car and shadow layers over the background into its composite and background
  // layers; waits for the GPU.
  void RunOnGpu(const RenderFrame& fr, const glm::dmat3& env_from_world, RenderTargets& targets);
  // The same from out's car, car_alpha and shadow into out's background and composite.
  void RunOnCpu(const RenderFrame& fr, const glm::dmat3& env_from_world, RenderResult* out) const;

 private:
  gl::Program program_{gl::NoCreate};
  sphere::EquirectImage environment_, image_;
  gl::Texture texture_{gl::NoCreate};  // the one bound: the equirect's or the image's
  bool is_image_ = false;
  std::optional<glm::dmat3> background_from_world_;
};

}  // namespace odvr::render
