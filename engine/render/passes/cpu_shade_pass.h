#pragma once
// The CPU path's shading: the CPU reference (detail::ShadeReference) over the read-back G-buffer,
// with supersampling's resolve and flags, or shading rate 2's flags and fill, as the GPU passes
// do them, so that a CPU render is the GPU's reference pixel for pixel. Internal to engine/render.
#include <vector>

#include "engine/render/passes/shade_inputs.h"

namespace odvr::render {

// Fills out's car, car_alpha, shadow, ground_mask and sampled_fully at the output's size, and per
// shaded sample its counts and, when supersampled, the car's coverage (out's car_alpha is that
// otherwise); VoxelizePass::Run on the CPU first.
void ShadeOnCpu(const RenderFrame& fr, const ShadeScene& scene, const detail::GBuffer& g, RenderResult* out,
                std::vector<detail::PixelCounts>* sample_counts, std::vector<float>* sample_alpha);

}  // namespace odvr::render
