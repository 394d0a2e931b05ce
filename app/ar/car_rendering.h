#pragma once
// How both players light and render the car (app/ar/augmented_scene.h, app/ar/live_scene.h): the
// settings their command lines fill, checked once, and the engine options they make.
#include "engine/lighting/lighting_builder.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::app {

struct CarRendering {
  int lighting_levels = 4;
  // Light frames wider than this are area-resampled to it before the lighting builder, which
  // finds the peaks there and box-averages the rest to the transform's grid in the same pass. An
  // HDR sun keeps its energy at any width, but an LDR one is only a clipped blob: at 1024 wide a
  // pixel is 0.35°, under the sun's disc, while at 256 a one-pixel clipped sun averages with its
  // ring below the clip level and the car loses its shadow.
  int lighting_width = 1024;
  int voxel_resolution = 64;
  int cone_rings = 1;
  int supersample = 1;   // render::RenderOptions::supersample (adaptive, its default contrast)
  int shading_rate = 1;  // render::RenderOptions::shading_rate (1 while supersample > 1)
  // A window's frames stay on the GPU: the frame's image is left empty and the scene's
  // composite() holds the picture, exposure not applied (FramePresenter applies it as it draws).
  bool composite_on_gpu = false;

  void Check() const;  // throws odvr::UsageError naming the option
  lighting::LightingOptions Lighting() const;
  // A player shows the composite alone: the layers are not read back, nor the composite when
  // it stays on the GPU.
  render::RenderOptions Render() const;
};

}  // namespace odvr::app
