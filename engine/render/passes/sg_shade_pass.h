#pragma once
// The SG shading pass (render_shade.comp, seed eq. 4.7's triple product per pixel): the ground's
// cone table, the ground-lit map, then every shaded sample — or, with adaptive supersampling, each
// pixel's centre sample and then the flagged pixels' others (render_flag.comp), or, at shading
// rate 2, a pixel of each 2×2 block, the flagged blocks' others and the rest filled
// (render_fill.comp). Writes RenderTargets' shaded car and shadow layers and the counts. Its CPU
// reference is detail::ShadeReference. Internal to engine/render.
#include <array>
#include <cstdint>

#include "engine/gl/objects.h"
#include "engine/render/passes/shade_inputs.h"

namespace odvr::render {

class SgShadePass {
 public:
  // Compiles what `options` needs: the flag and list passes for supersampling and shading rate 2,
  // the fill for rate 2, and, when options.shade_lanes is fixed, the shader of those lanes.
  explicit SgShadePass(const RenderOptions& options);

  // The shading lanes for a render of `camera`'s size (RenderOptions::shade_lanes, or
  // ShadeLanesFor), their shader compiled now.
  int PrepareLanes(const RenderOptions& options, const PinholeCamera& camera);

  // Shades fr's samples with `lanes` invocations a pixel (PrepareLanes). The GPU's work is
  // issued, not waited for.
  void Run(const RenderFrame& fr, const ShadeScene& scene, RenderTargets& targets, int lanes);

  // Shading rate 2, after Run: the pixels shaded (the rest were filled), and per block its flag.
  // Both wait for the GPU.
  long long HalfRateShadedPixels(const RenderFrame& fr) const;
  std::vector<std::uint8_t> ReadBlockFlags(const RenderFrame& fr) const;

 private:
  gl::Program& Program(int lanes);
  void SetUniforms(const RenderFrame& fr, const ShadeScene& scene, gl::Program& sp);
  void DispatchGroundLitMap(const RenderFrame& fr, const ShadeScene& scene, gl::Program& sp, int lanes);
  void ShadeHalfRate(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, int lanes);
  void ShadeAdaptive(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, int lanes);
  // render_flag.comp over flag_w × flag_h pixels (blocks, at shading_rate 2) of factor² samples
  // each, their flags into `flags` and the flagged ones into `list`; then render_shade.comp shades
  // the listed ones' other samples into car and shadow.
  void FlagAndShadeListed(const RenderFrame& fr, RenderTargets& targets, gl::Program& sp, gl::Buffer& flags,
                          gl::Buffer& list, int flag_w, int flag_h, int factor, gl::Texture& car, gl::Texture& shadow,
                          bool neighbour_reps);

  // render_shade.comp per lane count (1, 2, 4), compiled when a render first asks for it.
  std::array<gl::Program, 3> programs_{gl::Program(gl::NoCreate), gl::Program(gl::NoCreate), gl::Program(gl::NoCreate)};
  int cone_rings_ = 0;
  bool software_renderer_ = false;
  gl::Program flag_program_{gl::NoCreate}, list_args_program_{gl::NoCreate}, fill_program_{gl::NoCreate};
  // render_shade.comp's GroundTable: per cone of the ground's lobe, per traced peak, and the
  // unshadowed sum, the lighting the ground sees through it (one vec4 each).
  gl::Buffer ground_table_{gl::NoCreate};
  gl::Buffer ground_lit_map_{gl::NoCreate};  // GroundLitMap (RenderOptions::ground_lit_map_texels)
  // Shading rate 2: per 2×2 block its flag, and the flagged ones listed (a count, then the blocks'
  // indices), as RenderTargets' pixel flags and list are for supersampling.
  gl::Buffer block_flags_{gl::NoCreate}, block_list_{gl::NoCreate};
  gl::Buffer list_args_{gl::NoCreate};  // render_list_args.comp's output: the listed pass's work groups
};

}  // namespace odvr::render
