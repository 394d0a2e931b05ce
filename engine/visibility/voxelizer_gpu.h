#pragma once
// The GPU path of visibility (seed §4.3, DESIGN.md §5): voxelize a triangle soup into a 3D
// texture (rgba8: occupancy and the opacity along each axis), build its mips, trace batches
// of cones. Same conventions and results as VoxelGrid (voxel_grid.h), which is its reference.
//
// Why a compute shader and not the rasterizer: the seed voxelizes in one render pass, a geometry
// shader projecting each triangle on its dominant axis and enlarging it for conservativeness.
// The enlargement over-covers (by up to a voxel at sharp corners, so the result depends on the
// triangle's shape) and, without GL_NV/INTEL conservative rasterization, which software drivers lack,
// it is the only way to be conservative. A compute invocation per triangle walking the columns
// of its dominant axis does the same projection and then the exact triangle–box test: the
// voxels marked are exactly the CPU reference's (up to float rounding on exact contact), on
// every driver, still in one pass over the triangles. Its cost is load imbalance on huge
// triangles (one invocation walks a whole ground plane), which a scene's car does not have.
#include <glm/vec3.hpp>
#include <span>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/visibility/voxel_grid.h"

namespace odvr::visibility {

class VoxelizerGpu {
 public:
  // Needs a current OpenGL 4.5 context (compiles the shaders, allocates resolution³ bytes plus
  // mips); throws odvr::Error otherwise or for a bad spec. Every call needs that context.
  explicit VoxelizerGpu(const VoxelGridSpec& spec);

  // Clears the volume, voxelizes `vertices` (three per triangle) and rebuilds the mips.
  void Voxelize(std::span<const glm::vec3> vertices);
  // Triangles already on the GPU: `count` triangles of three vec4 vertices (xyz, w unused).
  void Voxelize(const gl::Buffer& vertices, std::size_t count);

  // Visibility per query (VoxelGrid::TraceCone's rules); waits for the result.
  std::vector<float> TraceCones(std::span<const ConeQuery> queries, const ConeTraceOptions& options = {});

  const VoxelGridSpec& spec() const { return spec_; }
  int levels() const { return spec_.levels(); }
  // The mipmapped volume (rgba8: occupancy, opacity along x, y, z; LINEAR_MIPMAP_LINEAR, zero
  // border) for other shaders to trace.
  const gl::Texture& texture() const { return volume_; }
  // One level as VoxelGrid stores it (x fastest), for tests.
  std::vector<std::uint8_t> ReadLevel(int level) const;
  // One level's axis opacities as VoxelGrid::Opacity stores them, for tests.
  std::vector<std::uint8_t> ReadOpacity(int level) const;

 private:
  void BuildMips();
  VoxelGridSpec spec_;
  gl::Program voxelize_{gl::NoCreate}, mip_{gl::NoCreate}, trace_{gl::NoCreate};
  gl::Texture volume_{gl::NoCreate};
  gl::Buffer vertices_{gl::NoCreate}, queries_{gl::NoCreate}, results_{gl::NoCreate};
};

}  // namespace odvr::visibility
