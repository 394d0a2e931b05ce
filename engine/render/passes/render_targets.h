#pragma once
// The textures and buffers a render's passes write and read: the G-buffer at the shaded size, the
// car and shadow layers at the shaded and the output size, the composite and the background, the
// per-sample counts, and supersampling's per-pixel flags. Internal to engine/render.
#include "engine/gl/objects.h"
#include "engine/render/passes/render_frame.h"
#include "engine/render/triple_product_internal.h"

namespace odvr::render {

struct RenderTargets {
  gl::Framebuffer framebuffer{gl::NoCreate};  // the G-buffer's four colour targets and depth
  gl::Texture g_position{gl::NoCreate}, g_normal{gl::NoCreate}, g_base{gl::NoCreate}, g_emission{gl::NoCreate},
      g_depth{gl::NoCreate};
  gl::Texture car_layer{gl::NoCreate}, shadow_layer{gl::NoCreate}, composite_layer{gl::NoCreate},
      background_layer{gl::NoCreate};
  // RenderOptions::supersample > 1: the shading's car and shadow layers at the G-buffer's size,
  // resolved into car_layer and shadow_layer at the output's.
  gl::Texture shaded_car{gl::NoCreate}, shaded_shadow{gl::NoCreate};
  // RenderOptions::supersample_contrast: per output pixel, and the flagged ones listed (a count,
  // then the pixels' indices).
  gl::Buffer pixel_flags{gl::NoCreate}, flagged_list{gl::NoCreate};
  gl::Buffer counts{gl::NoCreate};  // per shaded sample: lobes, cones, triples, SGs (uvec4)

  // The targets of `fr`'s sizes, made anew only when they change. Throws odvr::Error, before any
  // target is made, when the shaded size is beyond the GPU's textures.
  void Ensure(const RenderFrame& fr);
  // The layers the shading writes: the shaded-size ones when supersampled.
  gl::Texture& ShadedCar(const RenderFrame& fr) { return fr.k > 1 ? shaded_car : car_layer; }
  gl::Texture& ShadedShadow(const RenderFrame& fr) { return fr.k > 1 ? shaded_shadow : shadow_layer; }
  // The G-buffer read back for the CPU reference.
  detail::GBuffer ReadGBuffer() const;

 private:
  int fb_width_ = 0, fb_height_ = 0, out_width_ = 0, out_height_ = 0;
};

}  // namespace odvr::render
