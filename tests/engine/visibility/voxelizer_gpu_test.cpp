// The GPU voxelizer, mips and cone tracer against the CPU reference (voxel_grid.h):
// - occupancy: the same voxels on a box, a sphere, a tilted thin plate and a triangle on a
//   voxel face. Both sides run the same walk and the same separating-axis test, the GPU in
//   float and the CPU in double, so only exact-contact cases may differ: allowed are 0.1 % of
//   the marked voxels (measured: none differ on these meshes).
// - mips: every level within one 8-bit step (both round the same integer mean; only the
//   level-0 differences above could propagate); the axis opacities equal (the same integer
//   compositing) wherever level 0 agrees.
// - cones: within 0.02 in visibility. The texture unit filters with fixed-point weights
//   (llvmpipe: 8 bits), the CPU in double; over a trace's tens of samples that compounds to
//   the measured worst case recorded in the test output.
#include "engine/visibility/voxelizer_gpu.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <glm/geometric.hpp>
#include <random>

#include "core/error.h"
#include "engine/scene/gltf_scene.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/visibility/test_meshes.h"

namespace odvr::visibility {
namespace {

using odvr::testing::BoxMesh;
using odvr::testing::QuadMesh;
using odvr::testing::SphereMesh;
using VoxelizerGpuGL = odvr::testing::GlTest;

constexpr double kMaxDifferingFraction = 1e-3;
constexpr double kConeTolerance = 0.02;

// Voxelizes on both sides and compares every level; returns the CPU grid.
VoxelGrid ExpectSameVolumes(const VoxelGridSpec& spec, const std::vector<glm::vec3>& mesh, const char* name) {
  VoxelGrid cpu(spec);
  cpu.Voxelize(mesh);
  cpu.BuildMips();
  VoxelizerGpu gpu(spec);
  gpu.Voxelize(mesh);
  const auto level0 = gpu.ReadLevel(0);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < level0.size(); ++i) differ += (level0[i] != 0) != (cpu.Level(0)[i] != 0);
  EXPECT_LE(static_cast<double>(differ), kMaxDifferingFraction * static_cast<double>(cpu.OccupiedCount()))
      << name << ": " << differ << " of " << cpu.OccupiedCount() << " voxels differ";
  EXPECT_GT(cpu.OccupiedCount(), 0u) << name;
  for (int l = 1; l < cpu.levels(); ++l) {
    const auto g = gpu.ReadLevel(l);
    int worst = 0;
    for (std::size_t i = 0; i < g.size(); ++i) worst = std::max(worst, std::abs(int(g[i]) - int(cpu.Level(l)[i])));
    EXPECT_LE(worst, differ ? 1 : 0) << name << " level " << l;
    if (differ == 0) {
      EXPECT_EQ(gpu.ReadOpacity(l), cpu.Opacity(l)) << name << " axis opacities, level " << l;
    }
  }
  return cpu;
}

TEST_F(VoxelizerGpuGL, OccupancyAndMipsMatchTheCpu) {
  VoxelGridSpec unit;
  unit.resolution = 64;
  ExpectSameVolumes(unit, BoxMesh({5.25f, 8.f, 3.5f}, {40.75f, 17.f, 56.5f}), "box");
  ExpectSameVolumes(unit, SphereMesh({31.3f, 32.6f, 30.9f}, 20.f, 24, 48), "sphere");
  const glm::vec3 n = glm::normalize(glm::vec3(0.3f, 1.f, 0.45f));
  const glm::vec3 u = glm::normalize(glm::cross(n, glm::vec3(1, 0, 0))), v = glm::cross(n, u);
  ExpectSameVolumes(unit, QuadMesh({32.2f, 31.7f, 32.1f}, u, v, 150.f), "tilted plate");
  ExpectSameVolumes(unit, {{8, 2, 2}, {8, 10, 2}, {8, 2, 10}}, "triangle on a voxel face");
  // World units, a grid that does not start at the origin.
  const auto spec = VoxelGridSpec::Covering({-1.2, -0.3, -2}, {1.7, 2.1, 0.4}, 128);
  ExpectSameVolumes(spec, SphereMesh({0.2f, 0.9f, -0.8f}, 1.1f, 40, 80), "world sphere");
}

TEST_F(VoxelizerGpuGL, ConeTracesMatchTheCpu) {
  const auto spec = VoxelGridSpec::Covering({-3, -3, -3}, {3, 3, 3}, 64);
  std::vector<glm::vec3> scene = BoxMesh({0.5f, -3.f, -1.f}, {1.5f, -1.f, 1.f});
  const auto plate = BoxMesh({-2.5f, 0.5f, -2.5f}, {2.5f, 0.7f, 2.5f});
  scene.insert(scene.end(), plate.begin(), plate.end());
  const auto ball = SphereMesh({-1.5f, -2.f, 1.f}, 0.8f, 16, 32);
  scene.insert(scene.end(), ball.begin(), ball.end());
  VoxelGrid cpu(spec);
  cpu.Voxelize(scene);
  cpu.BuildMips();
  VoxelizerGpu gpu(spec);
  gpu.Voxelize(scene);

  std::mt19937 rng(3);
  std::uniform_real_distribution<float> pos(-2.5f, 2.5f), dir(-1.f, 1.f), angle(0.f, 1.f);
  std::vector<ConeQuery> queries;
  for (int i = 0; i < 400; ++i) {
    glm::vec3 d(dir(rng), dir(rng), dir(rng));
    if (glm::length(d) < 0.1f) d = {0, 1, 0};
    queries.push_back({{pos(rng), pos(rng) * 0.8f - 1.f, pos(rng)}, glm::normalize(d), 1.2f * angle(rng) * angle(rng)});
  }
  queries.push_back({{0, -0.5f, 0}, {0, 1, 0}, 0.0f});  // a ray
  queries.push_back({{9, 9, 9}, {1, 0, 0}, 0.3f});      // outside, leaving
  const auto g = gpu.TraceCones(queries);
  ASSERT_EQ(g.size(), queries.size());
  double worst = 0, mean = 0;
  std::size_t worst_at = 0;
  int partial = 0;
  for (std::size_t i = 0; i < queries.size(); ++i) {
    const double c = cpu.TraceCone(queries[i]);
    if (std::abs(c - g[i]) > worst) worst = std::abs(c - g[i]), worst_at = i;
    mean += std::abs(c - g[i]);
    partial += c > 0.05 && c < 0.95;
  }
  mean /= static_cast<double>(queries.size());
  const ConeQuery& w = queries[worst_at];
  EXPECT_LT(worst, kConeTolerance) << "cone " << worst_at << " from (" << w.origin.x << ", " << w.origin.y << ", "
                                   << w.origin.z << ") along (" << w.direction.x << ", " << w.direction.y << ", "
                                   << w.direction.z << "), half-angle " << w.half_angle << ": cpu " << cpu.TraceCone(w)
                                   << ", gpu " << g[worst_at];
  EXPECT_GT(partial, 20) << "the queries should exercise partial visibility";
  RecordProperty("cone_worst_abs_diff", std::to_string(worst));
  RecordProperty("cone_mean_abs_diff", std::to_string(mean));
  std::printf("cone trace gpu vs cpu: worst |Δ| %.4f, mean %.5f over %zu cones (%d partial)\n", worst, mean,
              queries.size(), partial);
}

TEST_F(VoxelizerGpuGL, PhysicalChecksOnTheGpu) {
  const auto spec = VoxelGridSpec::Covering({-2, -2, -2}, {2, 2, 2}, 64);
  VoxelizerGpu gpu(spec);
  // A slab above the origin: blocked upwards, clear downwards, for narrow to wide cones.
  gpu.Voxelize(BoxMesh({-1.8f, 0.5f, -1.8f}, {1.8f, 0.6f, 1.8f}));
  std::vector<ConeQuery> q;
  for (float a : {0.05f, 0.2f, 0.5f}) {
    q.push_back({{0.1f, 0, -0.2f}, {0, 1, 0}, a});
    q.push_back({{0.1f, 0, -0.2f}, {0, -1, 0}, a});
  }
  auto v = gpu.TraceCones(q);
  for (std::size_t i = 0; i < q.size(); i += 2) {
    EXPECT_LT(v[i], 0.05) << "up, half-angle " << q[i].half_angle;
    EXPECT_GT(v[i + 1], 0.99) << "down, half-angle " << q[i].half_angle;
  }
  // A ground point beside a box; a wide cone straddling the box's top edge sees part of the sky.
  gpu.Voxelize(BoxMesh({0.5f, -2.f, -1.f}, {1.5f, 0.f, 1.f}));
  const glm::vec3 p(-0.5f, -1.98f, 0.f);
  q = {{p, glm::normalize(glm::vec3(1, 0.3f, 0)), 0.1f},
       {p, glm::normalize(glm::vec3(-1, 0.3f, 0)), 0.1f},
       {p, {0, 1, 0}, 0.1f},
       {p, glm::normalize(glm::vec3(1, 2, 0)), 0.6f}};
  v = gpu.TraceCones(q);
  EXPECT_LT(v[0], 0.05);
  EXPECT_GT(v[1], 0.99);
  EXPECT_GT(v[2], 0.99);
  EXPECT_GT(v[3], 0.2);
  EXPECT_LT(v[3], 0.8);
}

TEST_F(VoxelizerGpuGL, EmptySceneAndBadInputs) {
  VoxelizerGpu gpu(VoxelGridSpec::Covering({0, 0, 0}, {1, 1, 1}, 16));
  gpu.Voxelize(std::vector<glm::vec3>{});
  for (auto x : gpu.ReadLevel(0)) ASSERT_EQ(x, 0);
  const std::vector<ConeQuery> q{{{0.5f, 0.5f, 0.5f}, {0, 0, 1}, 1.2f}};
  EXPECT_FLOAT_EQ(gpu.TraceCones(q)[0], 1.f);
  EXPECT_THROW(gpu.Voxelize(std::vector<glm::vec3>(5)), Error);
  EXPECT_THROW(gpu.TraceCones(std::vector<ConeQuery>{{{0, 0, 0}, {0, 0, 1}, 2.f}}), Error);
  VoxelGridSpec bad;
  bad.resolution = 100;
  EXPECT_THROW(VoxelizerGpu{bad}, Error);
}

// Measured CPU vs GPU voxelization of ToyCar (~100k triangles) at 128³; skipped without the file.
TEST_F(VoxelizerGpuGL, ToyCarCpuAndGpuAgreeAndAreTimed) {
  const std::filesystem::path path = std::filesystem::path(ODVR_SHARED_DIR) / "data/gltf/ToyCar.glb";
  if (!std::filesystem::exists(path)) GTEST_SKIP() << path << " is absent";
  const auto car = scene::LoadGltfScene(path);
  const auto soup = TriangleSoup(car);
  const auto spec = VoxelGridSpec::Covering(glm::dvec3(car.bounds.min), glm::dvec3(car.bounds.max), 128);
  using Clock = std::chrono::steady_clock;
  auto ms = [](Clock::time_point a) { return std::chrono::duration<double, std::milli>(Clock::now() - a).count(); };
  VoxelGrid cpu(spec);
  auto t0 = Clock::now();
  cpu.Voxelize(soup);
  const double cpu_ms = ms(t0);
  t0 = Clock::now();
  cpu.BuildMips();
  const double cpu_mip_ms = ms(t0);
  VoxelizerGpu gpu(spec);
  gpu.Voxelize(soup);  // warm-up: shader compilation and first allocation
  gl::Finish();
  t0 = Clock::now();
  gpu.Voxelize(soup);
  gl::Finish();
  const double gpu_ms = ms(t0);
  const auto level0 = gpu.ReadLevel(0);
  std::size_t differ = 0;
  for (std::size_t i = 0; i < level0.size(); ++i) differ += (level0[i] != 0) != (cpu.Level(0)[i] != 0);
  EXPECT_LE(static_cast<double>(differ), kMaxDifferingFraction * static_cast<double>(cpu.OccupiedCount()));
  std::printf(
      "ToyCar %zu triangles at 128^3: %zu voxels; cpu voxelize %.1f ms + mips %.1f ms; gpu (upload, "
      "voxelize, mips) %.1f ms on %s; %zu voxels differ\n",
      soup.size() / 3, cpu.OccupiedCount(), cpu_ms, cpu_mip_ms, gpu_ms,
      reinterpret_cast<const char*>(glGetString(GL_RENDERER)), differ);
  RecordProperty("cpu_voxelize_ms", std::to_string(cpu_ms));
  RecordProperty("gpu_voxelize_ms", std::to_string(gpu_ms));
}

}  // namespace
}  // namespace odvr::visibility
