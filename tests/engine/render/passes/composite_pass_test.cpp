// The composite pass (render_composite.comp): on its own it is the CPU's composite of the same
// layers; read back alone it is the same image, with the same counts; the background keeps its own
// rotation and stands alone without a model.
#include "engine/render/passes/composite_pass.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <random>
#include <vector>

#include "core/error.h"
#include "engine/render/triple_product_internal.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using odvr::testing::kH;
using odvr::testing::kW;
using odvr::testing::SphereAndBox;
using odvr::testing::SunnySky;
using odvr::testing::View;
using CompositePassGL = odvr::testing::GlTest;

// RenderOptions::supersample with every sample shaded (supersample_contrast 0): the GPU renders
// k² samples per pixel and resolves them (render_resolve.comp). Its output must be the same
// samples, rendered at k× the size without supersampling, resolved by the CPU reference
// (detail::ResolveSupersampled); the CPU shading path must agree as the unsupersampled paths do;
// and the car's silhouette must come out with fractional coverage (point sampling gives 0 or 1)
// while the covered area stays the same.
// The pass alone on random car and shadow layers: the GPU's composite is the CPU's over an
// equirectangular background (bilinear on both, so within the GPU's filtering precision) and
// equal to it over an image; and it is (1 − α) · background · shadow + α · car.
TEST_F(CompositePassGL, GpuCompositeIsTheCpuReferenceOfTheSameLayers) {
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> unit(0.f, 1.f);
  const RenderOptions o;
  const RenderFrame fr = RenderFrame::Make(o, View(), ShadeDevice::kGpu, true, {0, 0});
  RenderTargets targets;
  targets.Ensure(fr);
  RenderResult layers;
  layers.car = sphere::EquirectImage(fr.w, fr.h, 0.f);
  layers.shadow = sphere::EquirectImage(fr.w, fr.h, 1.f);
  layers.car_alpha.assign(fr.pixels, 0.f);
  layers.ground_mask.assign(fr.pixels, 0.f);
  std::vector<float> car(4 * fr.pixels), shadow(4 * fr.pixels);
  for (std::size_t i = 0; i < fr.pixels; ++i) {
    layers.car_alpha[i] = i % 3 == 0 ? 0.f : unit(rng);
    for (int c = 0; c < 3; ++c) {
      car[4 * i + c] = layers.car.rgb[3 * i + c] = 3 * unit(rng);
      shadow[4 * i + c] = layers.shadow.rgb[3 * i + c] = 0.2f + 0.8f * unit(rng);
    }
    car[4 * i + 3] = layers.car_alpha[i];
    shadow[4 * i + 3] = 0;
  }
  targets.car_layer.Upload2D(GL_RGBA, GL_FLOAT, car.data());
  targets.shadow_layer.Upload2D(GL_RGBA, GL_FLOAT, shadow.data());
  sphere::EquirectImage pano(128, 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 128; ++x)
      for (int c = 0; c < 3; ++c)
        pano.at(x, y)[c] = 0.2f + 0.15f * static_cast<float>(std::sin(0.3 * x + c) + std::cos(0.2 * y));
  sphere::EquirectImage image(fr.w, fr.h);
  for (float& v : image.rgb) v = unit(rng);
  const glm::dmat3 env_from_world(glm::dvec3(0, 0, 1), glm::dvec3(0, 1, 0), glm::dvec3(-1, 0, 0));
  CompositePass pass;
  for (const bool is_image : {false, true}) {
    SCOPED_TRACE(is_image ? "image" : "equirect");
    if (is_image) {
      pass.SetImage(image);
    } else {
      pass.SetEquirect(pano);
    }
    pass.RunOnGpu(fr, env_from_world, targets);
    RenderResult cpu = layers;
    pass.RunOnCpu(fr, env_from_world, &cpu);
    const std::vector<float> gpu = targets.composite_layer.Read<float>(GL_RGBA, GL_FLOAT, 4);
    const std::vector<float> gpu_background = targets.background_layer.Read<float>(GL_RGBA, GL_FLOAT, 4);
    double worst = 0, worst_background = 0, formula = 0;
    for (std::size_t i = 0; i < fr.pixels; ++i)
      for (int c = 0; c < 3; ++c) {
        worst = std::max(worst, std::abs(double(gpu[4 * i + c]) - cpu.composite.rgb[3 * i + c]));
        worst_background =
            std::max(worst_background, std::abs(double(gpu_background[4 * i + c]) - cpu.background.rgb[3 * i + c]));
        const double a = layers.car_alpha[i];
        const double expected =
            (1 - a) * cpu.background.rgb[3 * i + c] * layers.shadow.rgb[3 * i + c] + a * layers.car.rgb[3 * i + c];
        formula = std::max(formula, std::abs(expected - cpu.composite.rgb[3 * i + c]));
      }
    EXPECT_LT(worst, is_image ? 1e-6 : 0.01);
    EXPECT_LT(worst_background, is_image ? 1e-6 : 0.01);
    EXPECT_LT(formula, 1e-5);
    if (is_image) {
      EXPECT_EQ(cpu.background.rgb, image.rgb);
    }
  }
  pass.SetImage(sphere::EquirectImage(10, 10, 0.f));
  EXPECT_THROW(pass.CheckOutputSize(fr.w, fr.h), Error);
  EXPECT_NO_THROW(pass.CheckOutputSize(10, 10));
}

// RenderOptions::read_layers off (a player's renders): the composite alone comes back, and the
// counts summed on the GPU are the CPU's sums of the same samples, for every supersampling mode.
TEST_F(CompositePassGL, CompositeOnlyReadsBackTheSameImageAndCounts) {
  struct Mode {
    int k;
    double contrast;
    int shading_rate = 1;
  };
  for (const Mode mode : {Mode{1, 0.0}, Mode{2, 0.0}, Mode{2, 0.05}, Mode{1, 0.05, 2}}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.supersample = mode.k;
    o.supersample_contrast = mode.contrast;
    o.shading_rate = mode.shading_rate;
    TripleProductRenderer every(SphereAndBox(), glm::dmat4(1.0), o);
    o.read_layers = false;
    TripleProductRenderer composite_only(SphereAndBox(), glm::dmat4(1.0), o);
    every.SetLighting(SunnySky());
    composite_only.SetLighting(SunnySky());
    const RenderResult a = every.Render(View(), ShadeDevice::kGpu);
    const RenderResult b = composite_only.Render(View(), ShadeDevice::kGpu);
    ASSERT_EQ(b.composite.rgb, a.composite.rgb) << mode.k;
    EXPECT_TRUE(b.car.rgb.empty() && b.car_alpha.empty() && b.shadow.rgb.empty() && b.background.rgb.empty());
    const RenderCounts &x = a.counts, &y = b.counts;
    std::printf("k = %d, contrast %.2f: %d car samples, %d ground, %d pixels sampled fully, %lld cones, %lld triples\n",
                mode.k, mode.contrast, y.car_pixels, y.ground_pixels, y.pixels_sampled_fully, y.cones_total,
                y.triples_total);
    EXPECT_GT(y.car_pixels, 100) << mode.k;
    EXPECT_GT(y.ground_pixels, 10) << mode.k;
    EXPECT_GT(y.triples_total, 0) << mode.k;
    EXPECT_EQ(y.car_pixels, x.car_pixels) << mode.k;
    EXPECT_EQ(y.ground_pixels, x.ground_pixels) << mode.k;
    EXPECT_EQ(y.pixels_sampled_fully, x.pixels_sampled_fully) << mode.k;
    EXPECT_EQ(y.cones_total, x.cones_total) << mode.k;
    EXPECT_EQ(y.triples_total, x.triples_total) << mode.k;
    EXPECT_EQ(y.lighting_sgs, x.lighting_sgs);
    EXPECT_EQ(y.peaks, x.peaks);
    // Means of integer sums over the same count: equal to the last bit.
    EXPECT_EQ(y.lobes_per_car_pixel, x.lobes_per_car_pixel) << mode.k;
    EXPECT_EQ(y.cones_per_car_pixel, x.cones_per_car_pixel) << mode.k;
    EXPECT_EQ(y.sgs_per_car_pixel, x.sgs_per_car_pixel) << mode.k;
    EXPECT_EQ(y.triples_per_car_pixel, x.triples_per_car_pixel) << mode.k;
    // Nothing read back (a window draws composite_texture()): the texture holds the same picture,
    // rows top first.
    o.read_composite = false;
    TripleProductRenderer on_gpu(SphereAndBox(), glm::dmat4(1.0), o);
    on_gpu.SetLighting(SunnySky());
    const RenderResult c = on_gpu.Render(View(), ShadeDevice::kGpu);
    EXPECT_TRUE(c.composite.rgb.empty());
    EXPECT_EQ(c.counts.triples_total, x.triples_total) << mode.k;
    const std::vector<float> texels = on_gpu.composite_texture().Read<float>(GL_RGBA, GL_FLOAT, 4);
    ASSERT_EQ(texels.size() / 4, a.composite.rgb.size() / 3);
    std::size_t differ = 0;
    for (std::size_t i = 0; i < texels.size() / 4; ++i)
      for (int ch = 0; ch < 3; ++ch) differ += texels[4 * i + ch] != a.composite.rgb[3 * i + ch];
    EXPECT_EQ(differ, 0u) << mode.k;
  }
  RenderOptions bad;
  bad.read_composite = false;  // with read_layers on
  EXPECT_THROW(bad.Check(), odvr::Error);
}

// A player's background: one panorama turned by its own rotation (not the lighting's), sampled by
// the GPU composite as the CPU path samples it; without the model, the composite is that
// background alone.
TEST_F(CompositePassGL, BackgroundEquirectHasItsOwnRotationAndCanStandAlone) {
  RenderOptions o;
  o.voxel_resolution = 64;
  TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
  r.SetLighting(SunnySky());
  sphere::EquirectImage pano(128, 64);
  for (int y = 0; y < 64; ++y)
    for (int x = 0; x < 128; ++x)
      for (int c = 0; c < 3; ++c)
        pano.at(x, y)[c] = 0.2f + 0.15f * static_cast<float>(std::sin(0.3 * x + c) + std::cos(0.2 * y));
  r.SetBackgroundEquirect(pano);
  const RenderResult unturned = r.Render(View());
  const double angle = 0.7;  // about +Y
  const glm::dmat3 turn(glm::dvec3(std::cos(angle), 0, -std::sin(angle)), glm::dvec3(0, 1, 0),
                        glm::dvec3(std::sin(angle), 0, std::cos(angle)));
  r.SetBackgroundRotation(turn);
  const RenderResult gpu = r.Render(View()), cpu = r.Render(View(), ShadeDevice::kCpu);
  double gpu_cpu = 0, moved = 0, expected = 0;
  const PinholeCamera cam = View();
  for (int y = 0; y < kH; ++y)
    for (int x = 0; x < kW; ++x) {
      // The background where the direction, taken back into the panorama by the rotation, falls.
      const glm::dvec3 d = glm::transpose(turn) * cam.Ray(x + 0.5, y + 0.5);
      const glm::dvec2 p = sphere::EquirectPixel(d, 128, 64);
      const int px = std::clamp(static_cast<int>(p.x), 0, 127), py = std::clamp(static_cast<int>(p.y), 0, 63);
      for (int c = 0; c < 3; ++c) {
        gpu_cpu =
            std::max(gpu_cpu, static_cast<double>(std::abs(gpu.background.at(x, y)[c] - cpu.background.at(x, y)[c])));
        moved = std::max(moved,
                         static_cast<double>(std::abs(gpu.background.at(x, y)[c] - unturned.background.at(x, y)[c])));
        expected = std::max(expected, static_cast<double>(std::abs(gpu.background.at(x, y)[c] - pano.at(px, py)[c])));
      }
    }
  EXPECT_LT(gpu_cpu, 0.01);
  EXPECT_GT(moved, 0.1) << "the rotation turned the background";
  EXPECT_LT(expected, 0.08) << "within a texel's variation of the rotated look-up";
  const RenderResult alone = r.Render(View(), ShadeDevice::kGpu, false);
  EXPECT_EQ(alone.counts.car_pixels, 0);
  EXPECT_GT(gpu.counts.car_pixels, 100);
  EXPECT_EQ(alone.composite.rgb, alone.background.rgb);
  EXPECT_EQ(alone.background.rgb, gpu.background.rgb);
  std::printf("background: GPU vs CPU max %.4f, turned vs not max %.3f, vs the rotated look-up max %.3f\n", gpu_cpu,
              moved, expected);
}

TEST_F(CompositePassGL, HardCaseEmptySceneRendersTheBackground) {
  RenderOptions o;
  o.voxel_resolution = 64;
  TripleProductRenderer r(scene::GltfScene{}, glm::dmat4(1.0), o);
  r.SetLighting(SunnySky());
  sphere::EquirectImage bg(kW, kH, 0.25f);
  r.SetBackgroundImage(bg);
  for (ShadeDevice d : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    const RenderResult res = r.Render(View(), d);
    EXPECT_EQ(res.counts.car_pixels, 0);
    EXPECT_EQ(res.composite.rgb, bg.rgb);
  }
  // A background of the wrong size is refused, naming both sizes.
  r.SetBackgroundImage(sphere::EquirectImage(10, 10, 0.f));
  EXPECT_THROW(r.Render(View()), Error);
}

}  // namespace
}  // namespace odvr::render
