// A compute shader from shaders/ writes a table; the CPU convention must agree with it.
#include <cmath>
#include <numeric>

#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::gl {
namespace {

using ComputeGL = odvr::testing::GlTest;

TEST_F(ComputeGL, EquirectDirectionsShaderMatchesCpuConvention) {
  constexpr int kW = 64, kH = 32;
  Buffer table;
  table.Allocate(sizeof(float) * 4 * kW * kH);
  Program program = ShaderLibrary::Compute("equirect_directions.comp");
  program.Set("uSize", 0.f);  // wrong type is ignored by GL; set the right one next
  glProgramUniform2i(program.id(), program.Uniform("uSize"), kW, kH);
  table.BindBase(GL_SHADER_STORAGE_BUFFER, 0);
  program.DispatchCovering(kW, kH);
  glMemoryBarrier(GL_BUFFER_UPDATE_BARRIER_BIT);
  const std::vector<float> gpu = table.Read<float>();
  ASSERT_EQ(gpu.size(), 4u * kW * kH);

  double total_solid_angle = 0;
  double max_dir_err = 0, max_sa_err = 0;
  for (int row = 0; row < kH; ++row) {
    for (int col = 0; col < kW; ++col) {
      const auto d = sphere::EquirectPixelDirection(col, row, kW, kH);
      const float* g = &gpu[4 * (row * kW + col)];
      max_dir_err = std::max({max_dir_err, std::abs(g[0] - d.x), std::abs(g[1] - d.y), std::abs(g[2] - d.z)});
      max_sa_err = std::max(max_sa_err, std::abs(g[3] - sphere::EquirectPixelSolidAngle(row, kW, kH)));
      total_solid_angle += g[3];
    }
  }
  EXPECT_LT(max_dir_err, 1e-5);
  EXPECT_LT(max_sa_err, 1e-6);
  EXPECT_NEAR(total_solid_angle, 4 * kPi, 1e-4);
}

}  // namespace
}  // namespace odvr::gl
