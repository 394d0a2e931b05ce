// The counts pass (render_counts.comp): its per-group sums carry past 32 bits and equal the
// CPU's sums.
#include "engine/render/passes/counts_pass.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/render/triple_product_internal.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::render {
namespace {

using CountsPassGL = odvr::testing::GlTest;

// render_counts.comp's 64-bit sums: a frame's triples can pass 2³² (1280×720 samples × a few
// thousand each), so the low words must carry into the high ones, across work groups too.
TEST_F(CountsPassGL, CountSumsCarryPast32Bits) {
  // Three work groups, the last one partly used; then more samples than invocations, so that each
  // invocation carries over its own stride too.
  for (const auto& [w, h] : {std::pair{300, 2}, std::pair{1024, 300}}) {
    const int n = w * h;
    std::vector<glm::uvec4> counts(static_cast<std::size_t>(n));
    std::vector<float> car(4 * static_cast<std::size_t>(n), 0.f);
    unsigned long long lobes = 0, cones = 0, triples = 0, sgs = 0, cones_all = 0, triples_all = 0;
    long long car_samples = 0, ground_samples = 0;
    for (int i = 0; i < n; ++i) {
      const glm::uvec4 c(i % 3 == 0 ? 0u : 1u + i % 5, 0xF0000000u - 7u * i, 0xFFFFFFFFu - i, 3000000000u + i);
      counts[static_cast<std::size_t>(i)] = c;
      const bool on_car = i % 2 == 0;
      car[4 * static_cast<std::size_t>(i) + 3] = on_car ? 1.f : 0.f;
      cones_all += c.y;
      triples_all += c.z;
      if (on_car) {
        ++car_samples;
        lobes += c.x;
        cones += c.y;
        triples += c.z;
        sgs += c.w;
      } else if (c.x > 0) {
        ++ground_samples;
      }
    }
    CountsPass pass;
    gl::Buffer count_buffer, flags;
    count_buffer.Allocate(counts.size() * sizeof(glm::uvec4), counts.data());
    const std::vector<std::uint32_t> flag_values(static_cast<std::size_t>(n), 1u);
    flags.Allocate(flag_values.size() * 4, flag_values.data());
    gl::Texture image = gl::Texture::Create2D(GL_RGBA32F, w, h);
    image.Upload2D(GL_RGBA, GL_FLOAT, car.data());
    const detail::CountSums s = pass.SumOnGpu(count_buffer, &flags, image, w, h, n - 5);
    EXPECT_EQ(s.car, car_samples);
    EXPECT_EQ(s.ground, ground_samples);
    EXPECT_EQ(s.pixels_sampled_fully, n - 5);
    EXPECT_EQ(static_cast<unsigned long long>(s.lobes), lobes);
    EXPECT_EQ(static_cast<unsigned long long>(s.cones), cones);
    EXPECT_EQ(static_cast<unsigned long long>(s.sgs), sgs);
    EXPECT_EQ(static_cast<unsigned long long>(s.triples), triples);
    EXPECT_EQ(static_cast<unsigned long long>(s.cones_total), cones_all);
    EXPECT_EQ(static_cast<unsigned long long>(s.triples_total), triples_all);
    EXPECT_GT(triples_all, 100ull << 32);  // the case is one that carries
  }
}

// The GPU's sums are the CPU's (CountsPass::SumOnCpu, the CPU path's) over the same samples, with
// adaptive supersampling's flags counted where 1.
TEST_F(CountsPassGL, GpuSumsAreTheCpusSums) {
  const int w = 37, h = 23, n = w * h;
  std::vector<detail::PixelCounts> counts(static_cast<std::size_t>(n));
  std::vector<glm::uvec4> packed(counts.size());
  std::vector<float> alpha(counts.size()), car(4 * counts.size(), 0.f);
  std::vector<std::uint32_t> flag_values(counts.size());
  for (int i = 0; i < n; ++i) {
    const auto u = static_cast<unsigned>(i);
    const auto k = static_cast<std::size_t>(i);
    counts[k] = {u % 4, (7 * u) % 11, (13 * u) % 29, (5 * u) % 17};
    packed[k] = glm::uvec4(counts[k].lobes, counts[k].cones, counts[k].triples, counts[k].sgs);
    alpha[k] = i % 3 == 1 ? 0.f : 0.25f * static_cast<float>(i % 5);
    car[4 * k + 3] = alpha[k];
    flag_values[k] = i % 7 == 0 ? 0u : 1u;
  }
  const std::vector<std::uint8_t> sampled_fully(flag_values.begin(), flag_values.end());
  const detail::CountSums cpu = CountsPass::SumOnCpu(counts, alpha, sampled_fully);
  CountsPass pass;
  gl::Buffer count_buffer, flags;
  count_buffer.Allocate(packed.size() * sizeof(glm::uvec4), packed.data());
  flags.Allocate(flag_values.size() * 4, flag_values.data());
  gl::Texture image = gl::Texture::Create2D(GL_RGBA32F, w, h);
  image.Upload2D(GL_RGBA, GL_FLOAT, car.data());
  const detail::CountSums gpu = pass.SumOnGpu(count_buffer, &flags, image, w, h, n);
  EXPECT_GT(cpu.car, 0);
  EXPECT_GT(cpu.ground, 0);
  EXPECT_LT(cpu.pixels_sampled_fully, n);
  EXPECT_EQ(gpu.car, cpu.car);
  EXPECT_EQ(gpu.ground, cpu.ground);
  EXPECT_EQ(gpu.pixels_sampled_fully, cpu.pixels_sampled_fully);
  EXPECT_EQ(gpu.lobes, cpu.lobes);
  EXPECT_EQ(gpu.cones, cpu.cones);
  EXPECT_EQ(gpu.sgs, cpu.sgs);
  EXPECT_EQ(gpu.triples, cpu.triples);
  EXPECT_EQ(gpu.cones_total, cpu.cones_total);
  EXPECT_EQ(gpu.triples_total, cpu.triples_total);
}

}  // namespace
}  // namespace odvr::render
