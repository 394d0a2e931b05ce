// The resolve pass (render_resolve.comp) against its CPU reference, detail::ResolveSupersampled,
// on the same random shaded layers: every factor, every sample shaded or only the flagged pixels'.
#include "engine/render/passes/resolve_pass.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using ResolvePassGL = odvr::testing::GlTest;

// RGBA texels: rgb, then `alpha` per texel, as the shading writes its layers.
std::vector<float> Rgba(const sphere::EquirectImage& rgb, const std::vector<float>& alpha) {
  std::vector<float> v(4 * alpha.size());
  for (std::size_t i = 0; i < alpha.size(); ++i) {
    for (int c = 0; c < 3; ++c) v[4 * i + c] = rgb.rgb[3 * i + c];
    v[4 * i + 3] = alpha[i];
  }
  return v;
}

double MaxDifference(const std::vector<float>& gpu, const sphere::EquirectImage& rgb, const std::vector<float>& a) {
  const std::vector<float> cpu = Rgba(rgb, a);
  double worst = 0;
  for (std::size_t i = 0; i < cpu.size(); ++i) worst = std::max(worst, std::abs(double(gpu[i]) - cpu[i]));
  return worst;
}

TEST_F(ResolvePassGL, GpuResolveIsTheCpuReferenceForEveryFactorAndWithFlags) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> radiance(0.f, 4.f), ratio(0.2f, 1.f);
  for (int k = 2; k <= kMaxSupersample; ++k)
    for (const bool adaptive : {false, true}) {
      SCOPED_TRACE("k " + std::to_string(k) + (adaptive ? " adaptive" : ""));
      RenderOptions o;
      o.supersample = k;
      o.supersample_contrast = adaptive ? 0.1 : 0.0;
      const RenderFrame fr = RenderFrame::Make(o, odvr::testing::View(13, 9), ShadeDevice::kGpu, true, {0, 0});
      ASSERT_EQ(fr.adaptive, adaptive);
      RenderTargets targets;
      targets.Ensure(fr);
      // Shaded samples: the car covering some samples (alpha 0, ½ or 1), a shadow ratio and a
      // ground mask on the rest; adaptive, a random half of the pixels flagged.
      RenderResult shaded;
      shaded.car = sphere::EquirectImage(fr.sw, fr.sh, 0.f);
      shaded.shadow = sphere::EquirectImage(fr.sw, fr.sh, 1.f);
      shaded.car_alpha.assign(fr.samples, 0.f);
      shaded.ground_mask.assign(fr.samples, 0.f);
      for (std::size_t s = 0; s < fr.samples; ++s) {
        shaded.car_alpha[s] = 0.5f * static_cast<float>(rng() % 3);
        shaded.ground_mask[s] = shaded.car_alpha[s] < 1 && rng() % 2 ? 1.f : 0.f;
        for (int c = 0; c < 3; ++c) {
          shaded.car.rgb[3 * s + c] = shaded.car_alpha[s] > 0 ? radiance(rng) : 0.f;
          shaded.shadow.rgb[3 * s + c] = shaded.ground_mask[s] > 0 ? ratio(rng) : 1.f;
        }
      }
      std::vector<std::uint8_t> flags(fr.pixels);
      std::vector<std::uint32_t> flag_words(fr.pixels);
      for (std::size_t p = 0; p < fr.pixels; ++p) flag_words[p] = flags[p] = static_cast<std::uint8_t>(rng() % 2);
      targets.shaded_car.Upload2D(GL_RGBA, GL_FLOAT, Rgba(shaded.car, shaded.car_alpha).data());
      targets.shaded_shadow.Upload2D(GL_RGBA, GL_FLOAT, Rgba(shaded.shadow, shaded.ground_mask).data());
      targets.pixel_flags.SubData(0, flag_words.size() * 4, flag_words.data());

      ResolvePass pass;
      pass.Run(fr, targets);
      RenderResult expected;
      detail::ResolveSupersampled(shaded, k, fr.w, fr.h, &expected, adaptive ? &flags : nullptr);
      const std::vector<float> car = targets.car_layer.Read<float>(GL_RGBA, GL_FLOAT, 4);
      const std::vector<float> shadow = targets.shadow_layer.Read<float>(GL_RGBA, GL_FLOAT, 4);
      EXPECT_LT(MaxDifference(car, expected.car, expected.car_alpha), 1e-5);
      EXPECT_LT(MaxDifference(shadow, expected.shadow, expected.ground_mask), 1e-5);
      // Not a trivial case: partly covered pixels, and shadow ratios averaged under them.
      const auto partly = std::count_if(expected.car_alpha.begin(), expected.car_alpha.end(),
                                        [](float a) { return a > 0.05f && a < 0.95f; });
      EXPECT_GT(partly, static_cast<long>(fr.pixels / 2));
    }
}

}  // namespace
}  // namespace odvr::render
