// The counts pass (render_counts.comp): its per-group sums carry past 32 bits.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <utility>
#include <vector>

#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/render/triple_product_internal.h"
#include "tests/engine/gl/gl_test_context.h"

namespace odvr::render {
namespace {

using CountsGL = odvr::testing::GlTest;

// render_counts.comp's 64-bit sums: a frame's triples can pass 2³² (1280×720 samples × a few
// thousand each), so the low words must carry into the high ones, across work groups too.
TEST_F(CountsGL, CountSumsCarryPast32Bits) {
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
    gl::Program program = gl::ShaderLibrary::Compute("render_counts.comp");
    gl::Buffer count_buffer, flags, group_totals{gl::NoCreate};
    count_buffer.Allocate(counts.size() * sizeof(glm::uvec4), counts.data());
    const std::vector<std::uint32_t> flag_values(static_cast<std::size_t>(n), 1u);
    flags.Allocate(flag_values.size() * 4, flag_values.data());
    gl::Texture image = gl::Texture::Create2D(GL_RGBA32F, w, h);
    image.Upload2D(GL_RGBA, GL_FLOAT, car.data());
    const detail::CountSums s = detail::SumCountsOnGpu(program, count_buffer, &flags, group_totals, image, w, h, n - 5);
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

}  // namespace
}  // namespace odvr::render
