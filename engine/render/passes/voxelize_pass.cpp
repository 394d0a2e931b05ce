#include "engine/render/passes/voxelize_pass.h"

#include <algorithm>
#include <cmath>
#include <string>

#include "core/error.h"
#include "engine/gl/objects.h"

namespace odvr::render {

VoxelizePass::VoxelizePass(const GpuModel& model, const scene::GltfScene& source, int voxel_resolution) {
  if (!model.has_geometry()) {
    spec_ = visibility::VoxelGridSpec::Covering(glm::dvec3(-1), glm::dvec3(1), voxel_resolution);
    return;
  }
  // The loader bounds the model in its own frame; a model matrix can still scale it past what a
  // float voxel grid can hold. Say which model and how large, not "voxel size: inf".
  const scene::Bounds& bounds = model.bounds();
  const glm::dvec3 extent = glm::dvec3(bounds.max) - glm::dvec3(bounds.min);
  // The largest model taken: the loader's bound on a vertex's distance from the origin, across.
  const double max_extent_m = 2 * scene::GltfLoadOptions{}.max_coordinate_m;
  const double largest = std::max({extent.x, extent.y, extent.z});
  if (!std::isfinite(largest) || largest > max_extent_m)
    throw Error(source.source.string(), "placed by its model matrix it spans " + std::to_string(largest) +
                                            " m, more than the " + std::to_string(int(max_extent_m)) +
                                            " m a car's voxel grid can hold");
  spec_ = visibility::VoxelGridSpec::Covering(glm::dvec3(bounds.min), glm::dvec3(bounds.max), voxel_resolution);
  voxelizer_ = std::make_unique<visibility::VoxelizerGpu>(spec_);
}

void VoxelizePass::Run(const GpuModel& model, ShadeDevice device) {
  if (!model.has_geometry()) return;
  if (device == ShadeDevice::kGpu) {
    voxelizer_->Voxelize(model.triangle_buffer(), model.triangles().size() / 3);
    gl::Finish();
  } else {
    cpu_grid_ = std::make_unique<visibility::VoxelGrid>(spec_);
    cpu_grid_->Voxelize(model.triangles());
    cpu_grid_->BuildMips();
  }
}

}  // namespace odvr::render
