#pragma once
// TripleProductRenderer::Impl: the renderer's model, lighting and materials, and its passes
// (engine/render/passes/), which Render runs in order: voxelize, G-buffer, shade (SG or
// Monte-Carlo, on the GPU; the CPU reference on the CPU), resolve, composite, counts. Not part of
// the engine's API.
#include <array>
#include <optional>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/render/passes/composite_pass.h"
#include "engine/render/passes/counts_pass.h"
#include "engine/render/passes/gbuffer_pass.h"
#include "engine/render/passes/gpu_model.h"
#include "engine/render/passes/monte_carlo_shade_pass.h"
#include "engine/render/passes/render_frame.h"
#include "engine/render/passes/render_targets.h"
#include "engine/render/passes/resolve_pass.h"
#include "engine/render/passes/sg_shade_pass.h"
#include "engine/render/passes/shade_inputs.h"
#include "engine/render/passes/voxelize_pass.h"
#include "engine/render/triple_product_renderer.h"

namespace odvr::render {

struct TripleProductRenderer::Impl {
  // Needs a current OpenGL 4.5 context; compiles the passes `options` uses.
  Impl(const scene::GltfScene& source, const glm::dmat4& world_from_model, const RenderOptions& options);
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;
  ~Impl();

  GpuModel model;
  VoxelizePass voxelize;
  GpuMaterials materials;
  GpuLighting lighting;
  GBufferPass gbuffer;
  SgShadePass sg_shade;
  std::optional<MonteCarloShadePass> monte_carlo;  // RenderOptions::monte_carlo_samples > 0
  std::optional<ResolvePass> resolve;              // RenderOptions::supersample > 1
  CompositePass composite;
  std::optional<CountsPass> counts;  // RenderOptions::read_layers off: the counts summed on the GPU
  RenderTargets targets;
  gl::ReadbackBuffer readback;            // the layers and counts on their way to the CPU
  std::array<GLuint, 5> stage_queries{};  // GL timestamps between the GPU path's stages

  ShadeScene scene() const { return {model, voxelize, lighting, materials}; }

  // What a render's counts are summed from.
  struct Tally {
    std::vector<detail::PixelCounts> counts;    // per shaded sample, read back or the CPU's
    std::optional<detail::CountSums> gpu_sums;  // RenderOptions::read_layers off: summed on the GPU
    // The car's coverage per shaded sample when supersampled (the output's car_alpha otherwise).
    std::vector<float> sample_alpha;
  };

  // Render's checks (they throw before any GL call), then the frame.
  RenderFrame MakeFrame(const RenderOptions& options, const PinholeCamera& camera, ShadeDevice device,
                        bool draw_model) const;
  // GL timestamp `stage` (0..4) of the GPU path, between its stages; nothing on the CPU path.
  void Stamp(const RenderFrame& fr, int stage);
  void ReadStageTimes(RenderTimings* ms);
  // The GPU path after the G-buffer: shade, resolve, composite, read back.
  void RenderOnGpu(const RenderFrame& fr, RenderResult* out, Tally* tally);
  void ReadBack(const RenderFrame& fr, long long half_rate_shaded, RenderResult* out, Tally* tally);
  // The CPU path after the G-buffer: the CPU reference shades it, then the composite.
  void RenderOnCpu(const RenderFrame& fr, RenderResult* out, Tally* tally);
  void SumCounts(const RenderFrame& fr, const Tally& tally, RenderResult* out) const;
};

}  // namespace odvr::render
