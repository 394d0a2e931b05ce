#pragma once
// The renderer's first pass: the model's triangles into the voxel grid that the shading's cones
// trace (visibility/voxelizer_gpu.h on the GPU, its reference visibility/voxel_grid.h for the CPU
// path). Internal to engine/render.
#include <memory>

#include "engine/render/passes/gpu_model.h"
#include "engine/render/triple_product_renderer.h"
#include "engine/visibility/voxel_grid.h"
#include "engine/visibility/voxelizer_gpu.h"

namespace odvr::render {

class VoxelizePass {
 public:
  // The grid covering `model` at `voxel_resolution` voxels a side (a 2 m cube at the origin for a
  // model without triangles). Throws odvr::Error naming the model's file when it spans more than
  // a float grid can hold.
  VoxelizePass(const GpuModel& model, const scene::GltfScene& source, int voxel_resolution);

  // Voxelizes the model's triangles on `device` (and waits for the GPU).
  void Run(const GpuModel& model, ShadeDevice device);

  const visibility::VoxelGridSpec& spec() const { return spec_; }
  // The GPU's mipmapped volume (VoxelizerGpu::texture); needs a model with triangles.
  const gl::Texture& texture() const { return voxelizer_->texture(); }
  // The CPU's grid after a Run on the CPU; null before.
  const visibility::VoxelGrid* cpu_grid() const { return cpu_grid_.get(); }

 private:
  visibility::VoxelGridSpec spec_;
  std::unique_ptr<visibility::VoxelizerGpu> voxelizer_;
  std::unique_ptr<visibility::VoxelGrid> cpu_grid_;
};

}  // namespace odvr::render
