// The voxelize pass: the model's grid on the GPU is the CPU path's grid; a model without
// triangles gets a grid that occludes nothing; a model placed larger than a float grid can hold
// is refused, naming its file.
#include "engine/render/passes/voxelize_pass.h"

#include <gtest/gtest.h>

#include <glm/gtc/matrix_transform.hpp>
#include <string>

#include "core/error.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using VoxelizePassGL = odvr::testing::GlTest;

TEST_F(VoxelizePassGL, TheGpuGridIsTheCpuGrid) {
  // Turned and moved off the grid's planes: a box face lying exactly on a voxel boundary may mark
  // the voxels on either side (both are conservative), and the two voxelizers round it apart.
  const scene::GltfScene source = odvr::testing::SphereAndBox();
  const glm::dmat4 placed = glm::rotate(glm::translate(glm::dmat4(1.0), glm::dvec3(0.013, 0.021, 0.017)), 0.3,
                                        glm::normalize(glm::dvec3(1, 2, 3)));
  const GpuModel model(source, placed);
  VoxelizePass on_gpu(model, source, 64), on_cpu(model, source, 64);
  EXPECT_EQ(on_gpu.spec().resolution, 64);
  // The grid covers the model: both boxes' corners inside it.
  const glm::dvec3 lo = on_gpu.spec().origin, hi = lo + on_gpu.spec().side();
  for (int a = 0; a < 3; ++a) {
    EXPECT_LE(lo[a], model.bounds().min[a]);
    EXPECT_GE(hi[a], model.bounds().max[a]);
  }
  on_gpu.Run(model, ShadeDevice::kGpu);
  on_cpu.Run(model, ShadeDevice::kCpu);
  EXPECT_EQ(on_gpu.cpu_grid(), nullptr);
  ASSERT_NE(on_cpu.cpu_grid(), nullptr);
  const auto gpu = on_gpu.texture().Read<std::uint8_t>(GL_RED, GL_UNSIGNED_BYTE, 1, 0);
  const auto& cpu = on_cpu.cpu_grid()->Level(0);
  ASSERT_EQ(gpu.size(), cpu.size());
  std::size_t differ = 0;
  for (std::size_t i = 0; i < cpu.size(); ++i) differ += (gpu[i] != 0) != (cpu[i] != 0);
  const std::size_t occupied = on_cpu.cpu_grid()->OccupiedCount();
  EXPECT_GT(occupied, 1000u);
  std::size_t gpu_occupied = 0;
  for (auto v : gpu) gpu_occupied += v != 0;
  EXPECT_LE(static_cast<double>(differ), 1e-3 * static_cast<double>(occupied)) << gpu_occupied << " on the GPU";
}

TEST_F(VoxelizePassGL, HardCasesNoTrianglesAndAModelTooLargeForTheGrid) {
  const scene::GltfScene empty;
  const GpuModel nothing(empty, glm::dmat4(1.0));
  VoxelizePass pass(nothing, empty, 64);
  EXPECT_FALSE(nothing.has_geometry());
  EXPECT_EQ(pass.spec().resolution, 64);
  pass.Run(nothing, ShadeDevice::kCpu);
  EXPECT_EQ(pass.cpu_grid(), nullptr);

  scene::GltfScene huge = odvr::testing::SphereAndBox();
  huge.source = "huge_car.glb";
  const GpuModel scaled(huge, glm::scale(glm::dmat4(1.0), glm::dvec3(1e6)));
  try {
    VoxelizePass refused(scaled, huge, 64);
    FAIL() << "a model spanning 10^6 m was voxelized";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("huge_car.glb"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace odvr::render
