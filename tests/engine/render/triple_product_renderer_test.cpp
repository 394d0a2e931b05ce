// TripleProductRenderer (engine/render/triple_product_renderer.h) on small synthetic scenes:
// - the GPU shading pass against the CPU reference on the same G-buffer (96×64);
// - a furnace: a Lambertian sphere under a constant environment reads albedo × radiance times
//   the integral of brdf.h's clamped-cosine SG over the sphere (3.395 instead of π, +8.1 %);
// - the shadow catcher: darker under the car than far from it, absent without the car; and the
//   car's shadow on it darkening the ground's bounce that the car sees;
// - more lighting levels and more cones move the result towards the converged one;
// - the hard cases: Phong n = 10⁴, a car inside a peak's cone, zero-area triangles and
//   degenerate normals, an empty scene, a model far larger than the voxel volume, every
//   material parameter at its bound.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <numbers>

#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/gl/objects.h"
#include "engine/gl/shader_library.h"
#include "engine/lighting/sg.h"
#include "engine/render/triple_product_internal.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_scenes.h"
#include "tests/engine/visibility/test_meshes.h"

namespace odvr::render {
namespace {

using odvr::testing::BoxPrimitive;
using odvr::testing::FullLighting;
using odvr::testing::Pbr;
using odvr::testing::SkyRadiance;
using odvr::testing::SpherePrimitive;
using TripleProductRendererGL = odvr::testing::GlTest;

constexpr int kW = 96, kH = 64;

// A red glossy sphere beside a grey box on the ground.
scene::GltfScene SphereAndBox() {
  scene::GltfScene s;
  s.materials = {Pbr("paint", {0.6f, 0.1f, 0.05f}, 0.5f, 0.35f), Pbr("plastic", {0.5f, 0.5f, 0.5f}, 0.f, 0.8f)};
  s.primitives.push_back(SpherePrimitive({0, 0.5f, 0}, 0.5f, 0));
  s.primitives.push_back(BoxPrimitive({0.6f, 0, -0.6f}, {1.0f, 1.2f, 0.6f}, 1));
  odvr::testing::Finish(&s);
  return s;
}

PinholeCamera View(int w = kW, int h = kH) { return PinholeCamera::LookAt({-1.2, 1.6, 3.2}, {0.2, 0.4, 0}, 40, w, h); }

// Sky SGs on levels 0–3 plus a sun peak up and to the left, and a small constant.
lighting::SgLighting SunnySky(int levels = 4) {
  lighting::SgLighting l = FullLighting(levels, SkyRadiance);
  l.constant = glm::vec3(0.05f);
  l.peaks.push_back({glm::normalize(glm::dvec3(-0.6, 0.7, 0.3)), 3000.0, glm::vec3(2000.f, 1900.f, 1700.f)});
  return l;
}

bool AllFinite(const sphere::EquirectImage& img) {
  return std::all_of(img.rgb.begin(), img.rgb.end(), [](float v) { return std::isfinite(v); });
}

double Luma(const float* c) { return 0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]; }

struct Diff {
  double mean_rel = 0, p99_rel = 0, max_rel = 0;
  int pixels = 0;
};

// Relative luminance differences of `a` to `b` over the pixels where `mask` > 0.5.
Diff Compare(const sphere::EquirectImage& a, const sphere::EquirectImage& b, const std::vector<float>& mask,
             double floor = 1e-3) {
  std::vector<double> rel;
  for (std::size_t i = 0; i < mask.size(); ++i) {
    if (mask[i] <= 0.5f) continue;
    const double la = Luma(&a.rgb[3 * i]), lb = Luma(&b.rgb[3 * i]);
    rel.push_back(std::abs(la - lb) / std::max(lb, floor));
  }
  Diff d;
  d.pixels = static_cast<int>(rel.size());
  if (rel.empty()) return d;
  for (double r : rel) d.mean_rel += r;
  d.mean_rel /= static_cast<double>(rel.size());
  std::sort(rel.begin(), rel.end());
  d.p99_rel = rel[static_cast<std::size_t>(0.99 * static_cast<double>(rel.size() - 1))];
  d.max_rel = rel.back();
  return d;
}

TEST(TripleProductRenderer, CameraLookAtIsOpenCv) {
  const PinholeCamera c = PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 60, 200, 100);
  // Looking down −Z with +Y up: camera x = +X (right), y = −Y (down), z = −Z (forward).
  EXPECT_NEAR(glm::length(c.world_from_camera[0] - glm::dvec3(1, 0, 0)), 0, 1e-12);
  EXPECT_NEAR(glm::length(c.world_from_camera[1] - glm::dvec3(0, -1, 0)), 0, 1e-12);
  EXPECT_NEAR(glm::length(c.world_from_camera[2] - glm::dvec3(0, 0, -1)), 0, 1e-12);
  // The top row's centre ray: 49.5 pixels above the axis, f = 50 / tan 30°.
  const glm::dvec3 top = c.Ray(100, 0.5);
  EXPECT_NEAR(std::atan2(top.y, -top.z), std::atan(49.5 / 50 * std::tan(3.14159265358979 / 6)), 1e-12);
  EXPECT_NEAR(c.focal_px(), 50 / std::tan(3.14159265358979 / 6), 1e-9);
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 5}, 60, 200, 100), Error);
  EXPECT_THROW(PinholeCamera::LookAt({0, 5, 0}, {0, 0, 0}, 60, 200, 100), Error);  // straight down, up = +Y
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 0, 200, 100), Error);
  EXPECT_THROW(PinholeCamera::LookAt({0, 1, 5}, {0, 1, 0}, 60, 0, 100), Error);
}

TEST(TripleProductRenderer, ParsesMaterialOverrides) {
  const MaterialOverride a = ParseMaterialOverride("paint=0.3,0.6,200");
  EXPECT_EQ(a.material, "paint");
  ASSERT_EQ(a.brdfs.size(), 2u);
  EXPECT_DOUBLE_EQ(std::get<material::Lambertian>(a.brdfs[0]).albedo.x, 0.3);
  EXPECT_DOUBLE_EQ(std::get<material::Phong>(a.brdfs[1]).exponent, 200);
  const MaterialOverride b = ParseMaterialOverride("lambert:0.5,0.4,0.3+ct:0.9,0.8,0.7,0.1,beckmann");
  EXPECT_TRUE(b.material.empty());
  ASSERT_EQ(b.brdfs.size(), 2u);
  EXPECT_EQ(std::get<material::CookTorrance>(b.brdfs[1]).ndf, material::Ndf::kBeckmann);
  const MaterialOverride c = ParseMaterialOverride("glass=mr:0.1,0.1,0.1,0,0.05");
  EXPECT_DOUBLE_EQ(std::get<material::MetallicRoughness>(c.brdfs[0]).roughness, 0.05);
  for (const char* bad : {"", "paint=", "1,2", "0.7,0.6,10", "lambert:1,1", "phong:1,1,1,-1", "foo:1,2,3",
                          "ward:1,1,1,0", "lambert:1,1,x", "lambert:1,1,1+lambert:1,1,1+lambert:1,1,1"})
    EXPECT_THROW(ParseMaterialOverride(bad), UsageError) << bad;
}

TEST(TripleProductRenderer, CameraSizeBeyondItsLimitIsAClearError) {
  PinholeCamera camera;
  camera.width = PinholeCamera::kMaxSide;
  camera.height = 8;
  EXPECT_NO_THROW(camera.Check());
  for (const auto& [w, h] : {std::pair{PinholeCamera::kMaxSide + 1, 8}, std::pair{8, PinholeCamera::kMaxSide + 1},
                             std::pair{0, 8}, std::pair{8, -1}}) {
    camera.width = w;
    camera.height = h;
    try {
      camera.Check();
      ADD_FAILURE() << w << "x" << h << " accepted";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("camera size"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find(std::to_string(w) + "x" + std::to_string(h)), std::string::npos) << e.what();
    }
  }
}

TEST(TripleProductRenderer, OptionsAreChecked) {
  RenderOptions o;
  EXPECT_NO_THROW(o.Check());
  for (int r : {32, 96, 1024}) {
    RenderOptions bad;
    bad.voxel_resolution = r;
    EXPECT_THROW(bad.Check(), Error) << r;
  }
  RenderOptions levels;
  levels.lighting_levels = 7;
  EXPECT_THROW(levels.Check(), Error);
  RenderOptions rings;
  rings.cone_rings = 4;
  EXPECT_THROW(rings.Check(), Error);
  for (int k : {0, -1, kMaxSupersample + 1}) {
    RenderOptions bad;
    bad.supersample = k;
    EXPECT_THROW(bad.Check(), Error) << k;
  }
  for (double c : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    RenderOptions bad;
    bad.supersample_contrast = c;
    EXPECT_THROW(bad.Check(), Error) << c;
  }
  for (double c : {0.0, 1.0, std::numeric_limits<double>::quiet_NaN()}) {
    RenderOptions bad;
    bad.overlap_cutoff = c;
    EXPECT_THROW(bad.Check(), Error) << c;
  }
  for (int rate : {0, 3, 4}) {
    RenderOptions bad;
    bad.shading_rate = rate;
    EXPECT_THROW(bad.Check(), Error) << rate;
  }
  RenderOptions half_and_supersampled;
  half_and_supersampled.shading_rate = 2;
  half_and_supersampled.supersample = 2;
  EXPECT_THROW(half_and_supersampled.Check(), Error);
  RenderOptions half_and_mc;
  half_and_mc.shading_rate = 2;
  half_and_mc.monte_carlo_samples = 16;
  EXPECT_THROW(half_and_mc.Check(), Error);
}

// Cycles' default pixel filter: Blackman-Harris over 1.5 output pixels, 1 at the pixel's centre,
// symmetric, 0 at ±0.75 and beyond; at k = 2 that is the 2×2 box (the neighbours' samples lie at
// ±0.75 or farther), at k = 3 and 4 it reaches into the neighbouring pixels.
TEST(TripleProductRenderer, SupersampleWeightsAreCyclesPixelFilter) {
  for (int k = 1; k <= kMaxSupersample; ++k) {
    const std::vector<float> w = detail::SupersampleWeights(k);
    ASSERT_EQ(w.size(), static_cast<std::size_t>(3 * k));
    for (int j = -k; j < 2 * k; ++j) {
      const double offset = (j + 0.5) / k - 0.5;
      const float wj = w[static_cast<std::size_t>(j + k)];
      EXPECT_FLOAT_EQ(wj, w[static_cast<std::size_t>(k - 1 - j + k)]) << k << " " << j;  // offset → −offset
      if (std::abs(offset) >= 0.75 - 1e-12) {
        EXPECT_EQ(wj, 0.f) << k << " " << j;
      } else {
        EXPECT_GT(wj, 0.f) << k << " " << j;
      }
      if (std::abs(offset) < 1e-12) {
        EXPECT_NEAR(wj, 1.0, 1e-6);
      }
    }
  }
  const std::vector<float> box = detail::SupersampleWeights(2);
  EXPECT_EQ(box[0] + box[1] + box[4] + box[5], 0.f);
  EXPECT_FLOAT_EQ(box[2], box[3]);
  const std::vector<float> three = detail::SupersampleWeights(3);
  EXPECT_GT(three[2], 0.f);  // offset −2/3: the left neighbour's last sample
}

TEST_F(TripleProductRendererGL, GpuMatchesCpuReference) {
  RenderOptions o;
  o.voxel_resolution = 64;
  TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
  r.SetLighting(SunnySky());
  r.Render(View(), ShadeDevice::kGpu);  // llvmpipe compiles on first use (seconds): keep that out of the timing
  const RenderResult gpu = r.Render(View(), ShadeDevice::kGpu);
  const RenderResult cpu = r.Render(View(), ShadeDevice::kCpu);
  ASSERT_TRUE(AllFinite(gpu.car) && AllFinite(gpu.shadow));
  EXPECT_EQ(gpu.car_alpha, cpu.car_alpha);
  EXPECT_EQ(gpu.ground_mask, cpu.ground_mask);
  EXPECT_GT(gpu.counts.car_pixels, 500);
  const Diff car = Compare(gpu.car, cpu.car, gpu.car_alpha);
  double shadow_diff = 0, shadow_max = 0;
  int shadowed = 0;
  for (std::size_t i = 0; i < gpu.ground_mask.size(); ++i) {
    if (gpu.ground_mask[i] < 0.5f) continue;
    const double d = std::abs(Luma(&gpu.shadow.rgb[3 * i]) - Luma(&cpu.shadow.rgb[3 * i]));
    shadow_diff += d;
    shadow_max = std::max(shadow_max, d);
    shadowed += Luma(&cpu.shadow.rgb[3 * i]) < 0.9;
  }
  shadow_diff /= std::max(1, gpu.counts.ground_pixels);
  std::printf("GPU vs CPU: car %d px mean %.4f p99 %.4f max %.4f rel; shadow mean |d| %.4f max %.4f (%d px < 0.9)\n",
              car.pixels, car.mean_rel, car.p99_rel, car.max_rel, shadow_diff, shadow_max, shadowed);
  std::printf(
      "counts: %d SGs, %.1f lobes %.1f cones %.1f SGs %.1f triples per car pixel; shade gpu %.1f ms cpu %.1f ms\n",
      gpu.counts.lighting_sgs, gpu.counts.lobes_per_car_pixel, gpu.counts.cones_per_car_pixel,
      gpu.counts.sgs_per_car_pixel, gpu.counts.triples_per_car_pixel, gpu.ms.shade, cpu.ms.shade);
  EXPECT_GT(shadowed, 50);
  EXPECT_LT(car.mean_rel, 0.01);
  EXPECT_LT(car.p99_rel, 0.05);
  EXPECT_LT(shadow_diff, 0.01);
  // Both paths count the same work.
  EXPECT_NEAR(gpu.counts.lobes_per_car_pixel, cpu.counts.lobes_per_car_pixel, 0.01);
  // The split's lobes put a few right at the one-cone threshold, where float and double pick
  // different cone counts (measured 0.15 %).
  EXPECT_NEAR(gpu.counts.cones_per_car_pixel, cpu.counts.cones_per_car_pixel, 0.005 * cpu.counts.cones_per_car_pixel);
  EXPECT_NEAR(gpu.counts.sgs_per_car_pixel, cpu.counts.sgs_per_car_pixel, 0.02 * cpu.counts.sgs_per_car_pixel);
}

// The anisotropic split and the cosine as an SG (material::LobeOptions) in render_shade.comp
// against the CPU reference, which builds its lobes with material::AppendLobes itself.
// RenderOptions::depth_per_lobe: a bin's list goes as deep as the sharpest lobe it serves; each
// lobe taking only the levels the depth rule gives its own λ drops SGs it cannot show.
TEST_F(TripleProductRendererGL, DepthPerLobeDropsTheLevelsALobeCannotShow) {
  RenderResult result[2][2];  // [depth_per_lobe][gpu]
  for (bool depth : {false, true}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.lighting_levels = 5;
    o.depth_per_lobe = depth;
    TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
    r.SetLighting(SunnySky(5));
    result[depth][1] = r.Render(View(), ShadeDevice::kGpu);
    result[depth][0] = r.Render(View(), ShadeDevice::kCpu);
  }
  const RenderCounts &off = result[0][1].counts, &on = result[1][1].counts;
  const Diff change = Compare(result[1][1].car, result[0][1].car, result[1][1].car_alpha);
  std::printf(
      "SGs per car pixel: %.1f with every listed level, %.1f with each lobe's own (CPU %.1f); car mean %.4f "
      "p99 %.4f rel apart\n",
      off.sgs_per_car_pixel, on.sgs_per_car_pixel, result[1][0].counts.sgs_per_car_pixel, change.mean_rel,
      change.p99_rel);
  EXPECT_LT(on.sgs_per_car_pixel, 0.9 * off.sgs_per_car_pixel);
  EXPECT_NEAR(on.sgs_per_car_pixel, result[1][0].counts.sgs_per_car_pixel, 0.005 * on.sgs_per_car_pixel);
  EXPECT_NEAR(off.sgs_per_car_pixel, result[0][0].counts.sgs_per_car_pixel, 0.005 * off.sgs_per_car_pixel);
  EXPECT_LT(change.mean_rel, 0.01);
}

TEST_F(TripleProductRendererGL, GpuMatchesCpuReferenceForEveryLobeMode) {
  for (const auto warp : {material::WarpMode::kIsotropic, material::WarpMode::kAnisotropicSplit})
    for (const auto cosine : {material::CosineTerm::kAtLobeAxis, material::CosineTerm::kAsSg}) {
      if (warp == RenderOptions{}.lobes.warp && cosine == RenderOptions{}.lobes.cosine) continue;  // GpuMatchesCpu…
      RenderOptions o;
      o.voxel_resolution = 64;
      o.lobes = {cosine, warp};
      TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
      r.SetLighting(SunnySky());
      const RenderResult gpu = r.Render(View(48, 32), ShadeDevice::kGpu);
      const RenderResult cpu = r.Render(View(48, 32), ShadeDevice::kCpu);
      ASSERT_TRUE(AllFinite(gpu.car));
      const Diff car = Compare(gpu.car, cpu.car, gpu.car_alpha);
      std::printf("warp %d cosine %d: GPU vs CPU mean %.4f p99 %.4f rel; lobes per car pixel %.2f (CPU %.2f)\n",
                  static_cast<int>(warp), static_cast<int>(cosine), car.mean_rel, car.p99_rel,
                  gpu.counts.lobes_per_car_pixel, cpu.counts.lobes_per_car_pixel);
      EXPECT_LT(car.mean_rel, 0.01);
      EXPECT_LT(car.p99_rel, 0.05);
      EXPECT_NEAR(gpu.counts.lobes_per_car_pixel, cpu.counts.lobes_per_car_pixel,
                  0.01 * cpu.counts.lobes_per_car_pixel);
      if (warp == material::WarpMode::kAnisotropicSplit) {
        EXPECT_GT(gpu.counts.lobes_per_car_pixel, 2.5);
      }
    }
}

// RenderOptions::supersample with every sample shaded (supersample_contrast 0): the GPU renders
// k² samples per pixel and resolves them (render_resolve.comp). Its output must be the same
// samples, rendered at k× the size without supersampling, resolved by the CPU reference
// (detail::ResolveSupersampled); the CPU shading path must agree as the unsupersampled paths do;
// and the car's silhouette must come out with fractional coverage (point sampling gives 0 or 1)
// while the covered area stays the same.
// RenderOptions::read_layers off (a player's renders): the composite alone comes back, and the
// counts summed on the GPU are the CPU's sums of the same samples, for every supersampling mode.
TEST_F(TripleProductRendererGL, CompositeOnlyReadsBackTheSameImageAndCounts) {
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

// RenderOptions::shade_lanes: 2 or 4 invocations per pixel, each shading every L-th lobe, give
// the one-invocation picture (float sums in another order) and the same counts, with a peak
// (its cone and integrals summed across lanes), plainly and with adaptive supersampling (the
// listed samples' pass).
TEST_F(TripleProductRendererGL, ShadeLanesGiveTheSamePictureAndCounts) {
  PinholeCamera view = View();  // half size: the test renders six times
  view.width /= 2;
  view.height /= 2;
  for (int k : {1, 2}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.supersample = k;
    o.shade_lanes = 1;
    TripleProductRenderer one(SphereAndBox(), glm::dmat4(1.0), o);
    one.SetLighting(SunnySky());
    const RenderResult a = one.Render(view, ShadeDevice::kGpu);
    ASSERT_GE(a.counts.peaks, 1);
    EXPECT_EQ(a.counts.shade_lanes, 1);
    for (int lanes : {2, 4}) {
      o.shade_lanes = lanes;
      TripleProductRenderer split(SphereAndBox(), glm::dmat4(1.0), o);
      split.SetLighting(SunnySky());
      const RenderResult b = split.Render(view, ShadeDevice::kGpu);
      ASSERT_EQ(b.car.rgb.size(), a.car.rgb.size());
      double worst = 0, largest = 0;
      for (std::size_t i = 0; i < a.car.rgb.size(); ++i) {
        worst = std::max(worst, std::abs(static_cast<double>(b.car.rgb[i]) - a.car.rgb[i]));
        largest = std::max(largest, static_cast<double>(std::abs(a.car.rgb[i])));
      }
      std::printf("k = %d, %d lanes: largest difference %.3g, largest value %.3g\n", k, lanes, worst, largest);
      EXPECT_GT(a.counts.car_pixels, 50);
      // Float sums in another order: measured at most 1e-7 of the largest value.
      EXPECT_LE(worst, 1e-5 * largest) << k << " " << lanes;
      EXPECT_EQ(b.car_alpha, a.car_alpha) << k << " " << lanes;
      EXPECT_EQ(b.shadow.rgb, a.shadow.rgb) << k << " " << lanes;
      EXPECT_EQ(b.counts.car_pixels, a.counts.car_pixels);
      EXPECT_EQ(b.counts.ground_pixels, a.counts.ground_pixels);
      EXPECT_EQ(b.counts.pixels_sampled_fully, a.counts.pixels_sampled_fully);
      EXPECT_EQ(b.counts.cones_total, a.counts.cones_total) << k << " " << lanes;
      EXPECT_EQ(b.counts.triples_total, a.counts.triples_total) << k << " " << lanes;
      EXPECT_EQ(b.counts.lobes_per_car_pixel, a.counts.lobes_per_car_pixel);
      EXPECT_EQ(b.counts.shade_lanes, lanes);
    }
  }
  RenderOptions bad;
  bad.shade_lanes = 3;
  EXPECT_THROW(bad.Check(), odvr::Error);
}

// Mean luminance (channels summed) of the car pixels whose ray meets the plane y = plane_y in
// front of the camera within x in [x0, x1], |z| <= z_half; at least 50 of them expected.
double MeanOnPlane(const PinholeCamera& view, const RenderResult& r, double plane_y, double x0, double x1,
                   double z_half) {
  double sum = 0;
  int n = 0;
  for (int y = 0; y < view.height; ++y)
    for (int x = 0; x < view.width; ++x) {
      const std::size_t i = static_cast<std::size_t>(y) * view.width + x;
      const glm::dvec3 d = view.Ray(x + 0.5, y + 0.5);
      const double t = (plane_y - view.position.y) / d.y;
      if (r.car_alpha[i] < 0.5f || !(t > 0) || std::isinf(t)) continue;
      const glm::dvec3 p = view.position + t * d;
      if (p.x < x0 || p.x > x1 || std::abs(p.z) > z_half) continue;
      sum += r.car.rgb[3 * i] + r.car.rgb[3 * i + 1] + r.car.rgb[3 * i + 2];
      ++n;
    }
  EXPECT_GT(n, 50);
  return sum / std::max(n, 1);
}

// RenderOptions::exact_peak_shadows: a floor under a roof 4 cm above it (about a voxel at 64³
// over the scene), lit by a sun straight above, seen from inside the gap. The sun's cone starts 2
// voxels off the floor, past the roof, and lets the sun through as if there were no roof; a ray
// stops at the roof. GPU and CPU reference alike.
TEST_F(TripleProductRendererGL, ExactPeakShadowsSeeARoofNearerThanTheConesStart) {
  const auto scene = [](bool roof) {
    scene::GltfScene s;
    s.materials = {Pbr("floor", {0.5f, 0.5f, 0.5f}, 0.f, 0.9f)};
    s.primitives.push_back(BoxPrimitive({-1.f, 0.40f, -1.f}, {1.f, 0.42f, 1.f}, 0));
    if (roof) s.primitives.push_back(BoxPrimitive({-1.f, 0.46f, -1.f}, {0.f, 0.48f, 1.f}, 0));  // over x < 0
    odvr::testing::Finish(&s);
    return s;
  };
  lighting::SgLighting sun;
  sun.constant = glm::vec3(0.01f);
  sun.peaks.push_back({glm::dvec3(0, 1, 0), 3000.0, glm::vec3(3000.f)});
  const PinholeCamera view = PinholeCamera::LookAt({0.9, 0.45, 0.0}, {-0.5, 0.42, 0.0}, 6, 96, 48);
  // The floor's top under the roof (x in [−0.8, −0.2]).
  const auto under_roof = [&](const RenderResult& r) { return MeanOnPlane(view, r, 0.42, -0.8, -0.2, 0.5); };
  double lum[2][2][2];  // [exact][roof][device: gpu, cpu]
  for (bool exact : {false, true})
    for (bool roof : {false, true}) {
      RenderOptions o;
      o.voxel_resolution = 64;
      o.ground = false;
      o.exact_peak_shadows = exact;
      TripleProductRenderer r(scene(roof), glm::dmat4(1.0), o);
      r.SetLighting(sun);
      lum[exact][roof][0] = under_roof(r.Render(view, ShadeDevice::kGpu));
      lum[exact][roof][1] = under_roof(r.Render(view, ShadeDevice::kCpu));
      std::printf("%s, %s: the floor under the roof's place %.3f (CPU %.3f)\n", exact ? "rays" : "cones",
                  roof ? "roof" : "no roof", lum[exact][roof][0], lum[exact][roof][1]);
    }
  for (int device : {0, 1}) {
    EXPECT_GT(lum[0][0][device], 1.0) << device;                       // the sun lights the open floor
    EXPECT_GT(lum[0][1][device], 0.8 * lum[0][0][device]) << device;   // the cone leaks under the roof
    EXPECT_LT(lum[1][1][device], 0.05 * lum[1][0][device]) << device;  // the ray does not
    EXPECT_NEAR(lum[1][0][device], lum[0][0][device], 0.02 * lum[0][0][device]) << device;  // alike in the open
  }
  for (bool exact : {false, true})
    for (bool roof : {false, true})
      EXPECT_NEAR(lum[exact][roof][0], lum[exact][roof][1], 0.02 * lum[exact][0][0]) << exact << roof;
}

// The car's bounce off the ground it shadows takes the peaks' rays too: a board 0.3 m up, under a
// sun straight above, leaves the ground beneath it in its shadow. A pebble 6 m away widens the
// voxel cube to 64 voxels of 11 cm, so a cone from the ground starts 0.44 m up, past the board,
// and the cones light that ground; the rays do not, and the
// board's underside, which sees only that ground, is darker by the sun's share of the ground's
// light. Before the ground's lit fraction took the rays, both read alike.
TEST_F(TripleProductRendererGL, TheGroundsLitFractionTakesThePeaksRays) {
  scene::GltfScene board;
  board.materials = {Pbr("board", {0.8f, 0.8f, 0.8f}, 0.f, 0.9f)};
  board.primitives.push_back(BoxPrimitive({-1.f, 0.30f, -1.f}, {0.f, 0.32f, 1.f}, 0));
  board.primitives.push_back(BoxPrimitive({6.f, 0.f, 0.f}, {6.1f, 0.1f, 0.1f}, 0));
  odvr::testing::Finish(&board);
  lighting::SgLighting sun;
  sun.constant = glm::vec3(1.f);  // the ground's bounce: the lighting below the horizon
  sun.peaks.push_back({glm::dvec3(0, 1, 0), 3000.0, glm::vec3(3000.f)});
  const PinholeCamera view = PinholeCamera::LookAt({1.2, 0.1, 0.0}, {-0.5, 0.3, 0.0}, 40, 96, 48);
  // The board's underside over x in [−0.8, −0.2].
  const auto underside = [&](const RenderResult& r) { return MeanOnPlane(view, r, 0.30, -0.8, -0.2, 0.5); };
  double lum[2][2];  // [exact][device: gpu, cpu]
  for (bool exact : {false, true}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.exact_peak_shadows = exact;
    TripleProductRenderer r(board, glm::dmat4(1.0), o);
    r.SetLighting(sun);
    lum[exact][0] = underside(r.Render(view, ShadeDevice::kGpu));
    lum[exact][1] = underside(r.Render(view, ShadeDevice::kCpu));
    std::printf("%s: the board's underside %.4f (CPU %.4f)\n", exact ? "rays" : "cones", lum[exact][0], lum[exact][1]);
  }
  for (int device : {0, 1}) {
    EXPECT_GT(lum[0][device], 0.1) << device;                    // the ground's bounce reaches it
    EXPECT_LT(lum[1][device], 0.75 * lum[0][device]) << device;  // less of it with the rays
  }
  for (bool exact : {false, true}) EXPECT_NEAR(lum[exact][0], lum[exact][1], 0.02 * lum[exact][0]) << exact;
}

// RenderOptions::valid_reflection_normals: a mirror slab whose top's vertex normals lean 30° away
// from a camera 10° above it. The view mirrored about those normals dives 32° below the top, into
// the slab; tilted toward the face just enough, it leaves at a grazing height and sees a light
// 3° above the horizon beyond the slab. The GPU and the CPU shade the same G-buffer.
TEST_F(TripleProductRendererGL, ValidReflectionNormalsKeepTheMirroredViewAboveTheFace) {
  scene::GltfScene slab;
  slab.materials = {Pbr("slab", {0.8f, 0.8f, 0.8f}, 0.f, 0.5f)};
  scene::ScenePrimitive box = BoxPrimitive({-1.f, 0.48f, -1.f}, {1.f, 0.50f, 1.f}, 0);
  const glm::vec3 leaning = glm::normalize(glm::vec3(0.5f, 0.866f, 0.f));            // 30° toward +x
  for (int v = 12; v < 16; ++v) box.normals[static_cast<std::size_t>(v)] = leaning;  // the +y face
  slab.primitives.push_back(box);
  odvr::testing::Finish(&slab);
  lighting::SgLighting light;
  light.peaks.push_back({glm::normalize(glm::dvec3(1, 0.05, 0)), 200.0, glm::vec3(50.f)});
  const double elevation = 10.0 * std::numbers::pi / 180;
  const PinholeCamera view =
      PinholeCamera::LookAt({-3.0, 0.5 + 3.0 * std::tan(elevation), 0.0}, {0.0, 0.5, 0.0}, 20, 96, 48);
  double lum[2][2];  // [valid][device: gpu, cpu]
  for (bool valid : {false, true}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    o.valid_reflection_normals = valid;
    o.materials = {ParseMaterialOverride("phong:1,1,1,10000")};
    TripleProductRenderer r(slab, glm::dmat4(1.0), o);
    r.SetLighting(light);
    lum[valid][0] = MeanOnPlane(view, r.Render(view, ShadeDevice::kGpu), 0.50, -0.9, 0.9, 0.9);
    lum[valid][1] = MeanOnPlane(view, r.Render(view, ShadeDevice::kCpu), 0.50, -0.9, 0.9, 0.9);
    std::printf("%s normals: the slab's top %.4f (CPU %.4f)\n", valid ? "valid-reflection" : "interpolated",
                lum[valid][0], lum[valid][1]);
  }
  for (int device : {0, 1}) {
    EXPECT_GT(lum[1][device], 0.5) << device;                    // the light, mirrored
    EXPECT_LT(lum[0][device], 0.02 * lum[1][device]) << device;  // the inside of the slab: nothing
  }
  for (bool valid : {false, true}) EXPECT_NEAR(lum[valid][0], lum[valid][1], 0.02 * lum[1][0] + 1e-4) << valid;
}

// RenderOptions::specular_bounce: a mirror floor (Phong n = 10 000, reflectance 0.5) in front of
// an emissive wall, in the dark. Where the floor mirrors the wall its cone is blocked, and without
// the bounce the floor reads black; with it, the floor's lost light is the wall's radiance, which
// the G-buffer march finds: the same floor under an open sky of that radiance reads the same. GPU
// and CPU alike.
TEST_F(TripleProductRendererGL, SpecularBounceShowsAnEmissiveWallInAMirrorFloor) {
  const float radiance = 3.f;
  const auto scene = [&](bool wall) {
    scene::GltfScene s;
    s.materials = {Pbr("floor", {0.5f, 0.5f, 0.5f}, 0.f, 0.5f), Pbr("wall", {0.f, 0.f, 0.f}, 0.f, 1.f)};
    s.materials[1].emissive_factor = glm::vec3(1.f);
    s.materials[1].emissive_strength = radiance;
    s.primitives.push_back(BoxPrimitive({-2.f, -0.05f, -1.2f}, {2.f, 0.f, 2.f}, 0));
    if (wall) s.primitives.push_back(BoxPrimitive({-2.f, 0.f, -1.2f}, {2.f, 1.5f, -1.f}, 1));
    odvr::testing::Finish(&s);
    return s;
  };
  const PinholeCamera view = PinholeCamera::LookAt({0.0, 1.0, 3.0}, {0.0, 0.3, -0.5}, 50, 96, 64);
  const auto floor_mean = [&](bool wall, bool bounce, ShadeDevice device, int lanes = 1) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    o.specular_bounce = bounce;
    o.shade_lanes = lanes;
    o.materials = {ParseMaterialOverride("floor=phong:0.5,0.5,0.5,10000")};
    TripleProductRenderer r(scene(wall), glm::dmat4(1.0), o);
    lighting::SgLighting light;
    if (!wall) light.constant = glm::vec3(radiance);  // the open sky the wall stands for
    r.SetLighting(light);
    return MeanOnPlane(view, r.Render(view, device), 0.0, -1.0, 1.0, 0.4);
  };
  for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    const double sky = floor_mean(false, true, device), bounce = floor_mean(true, true, device),
                 none = floor_mean(true, false, device);
    std::printf("%s: the floor mirroring an open sky %.4f, the wall with the bounce %.4f, without %.4f\n",
                device == ShadeDevice::kGpu ? "GPU" : "CPU", sky, bounce, none);
    EXPECT_GT(sky, 0.3 * radiance);  // three channels of 0.5 × 3 × the cosine at the mirror (~0.3 here)
    EXPECT_NEAR(bounce / sky, 1.0, 0.1);
    EXPECT_LT(none, 0.02 * sky);
    // The bounce's sums of four lanes added up (render_shade.comp's second exchange).
    if (device == ShadeDevice::kGpu) {
      EXPECT_NEAR(floor_mean(true, true, device, 4), bounce, 1e-5 * bounce);
    }
  }
}

// A peak wider than 1° is seven rays, the axis and a ring whose second moment is the SG's: a lamp's
// penumbra. A sun is one ray.
TEST(PeakRays, OneForASunSevenForALamp) {
  const glm::dvec3 axis = glm::normalize(glm::dvec3(0.3, 0.8, -0.2));
  const auto sun = detail::PeakRayDirections(axis, 20000.0);  // half-value 0.48°
  ASSERT_EQ(sun.size(), 1u);
  EXPECT_EQ(sun[0], axis);
  for (double lambda : {3000.0, 300.0}) {  // 1.2° and 3.9°
    const auto lamp = detail::PeakRayDirections(axis, lambda);
    ASSERT_EQ(lamp.size(), 7u);
    EXPECT_EQ(lamp[0], axis);
    double second = 0;
    glm::dvec3 mean(0);
    for (const auto& d : lamp) {
      EXPECT_NEAR(glm::length(d), 1.0, 1e-12);
      const double t = std::acos(std::clamp(glm::dot(d, axis), -1.0, 1.0));
      second += t * t / 7;
      mean += d / 7.0;
    }
    EXPECT_NEAR(second, 2 / lambda, 0.05 * 2 / lambda) << lambda;  // E[θ²] of e^{λ(cos θ − 1)}
    EXPECT_NEAR(glm::length(glm::cross(glm::normalize(mean), axis)), 0.0, 1e-9) << lambda;
  }
}

// The ground under a wide lamp has a penumbra as wide as the lamp: the shadow ratio takes values
// between its umbra's and the open ground's on more pixels than under a sun, GPU and CPU alike.
TEST_F(TripleProductRendererGL, AWidePeakCastsAPenumbra) {
  const auto penumbra = [](double lambda) {
    lighting::SgLighting l;
    l.constant = glm::vec3(0.02f);
    l.peaks.push_back({glm::normalize(glm::dvec3(-0.4, 1.0, 0.2)), lambda, glm::vec3(static_cast<float>(lambda))});
    RenderOptions o;
    o.voxel_resolution = 64;
    TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
    r.SetLighting(l);
    std::array<int, 2> partial{};
    int d = 0;
    for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
      const RenderResult res = r.Render(View(), device);
      for (std::size_t i = 0; i < res.ground_mask.size(); ++i) {
        const double ratio = Luma(&res.shadow.rgb[3 * i]);
        partial[d] += res.ground_mask[i] > 0.5f && ratio > 0.2 && ratio < 0.8;
      }
      ++d;
    }
    std::printf("lambda %.0f: %d ground pixels in the penumbra (CPU %d)\n", lambda, partial[0], partial[1]);
    EXPECT_NEAR(partial[0], partial[1], 0.1 * partial[1] + 5) << lambda;
    return partial[0];
  };
  const int sun = penumbra(30000.0), lamp = penumbra(150.0);  // half-value 0.39° and 5.5°
  EXPECT_GT(lamp, 3 * sun + 20);
}

// shade_lanes 0 (the default): 4 lanes only where one invocation per pixel would leave a GPU
// mostly idle (320×180, as the H200 measured: 7.4 ms against 12.4), 1 where the pass fills it
// (1280×720: 27.0 against 35.7 with 4) and on a CPU rasterizer at any size.
TEST(ShadeLanes, FourOnlyOnSmallPassesOnAGpu) {
  EXPECT_EQ(ShadeLanesFor(320 * 180, false), 4);
  EXPECT_EQ(ShadeLanesFor(kAutoShadeLanesMaxPixels, false), 4);
  EXPECT_EQ(ShadeLanesFor(kAutoShadeLanesMaxPixels + 1, false), 1);
  EXPECT_EQ(ShadeLanesFor(640 * 360, false), 1);  // 1280×720 at shading rate 2: its blocks
  EXPECT_EQ(ShadeLanesFor(1280 * 720, false), 1);
  EXPECT_EQ(ShadeLanesFor(320 * 180, true), 1);
  EXPECT_EQ(ShadeLanesFor(1, true), 1);
  EXPECT_EQ(RenderOptions{}.shade_lanes, 0);
  // The first pass the pick looks at: the pixels, the 2×2 blocks at rate 2 (an odd edge's block
  // whole), the centre samples of adaptive supersampling, every sample when it shades them all.
  RenderOptions o;
  EXPECT_EQ(detail::FirstShadingPassPixels(o, 320, 180), 320 * 180);
  o.shading_rate = 2;
  EXPECT_EQ(detail::FirstShadingPassPixels(o, 321, 181), 161 * 91);
  o.shading_rate = 1;
  o.supersample = 2;
  EXPECT_EQ(detail::FirstShadingPassPixels(o, 320, 180), 320 * 180);
  o.supersample_contrast = 0;
  EXPECT_EQ(detail::FirstShadingPassPixels(o, 320, 180), 640 * 360);
}

// Each render says the lanes it shaded with: the rule's pick for its first pass on this device
// (the pixels at rate 1, the 2×2 blocks at rate 2), what it was told otherwise, 0 on the CPU.
TEST_F(TripleProductRendererGL, ShadeLanesArePickedPerRender) {
  const bool software = odvr::gl::CurrentRendererIsSoftware();
  for (int rate : {1, 2}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.shading_rate = rate;
    TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), o);
    r.SetLighting(SunnySky());
    for (int width : {64, 512}) {
      PinholeCamera view = View();
      view.height = view.height * width / view.width;
      view.width = width;
      const long long first_pass = rate == 2 ? static_cast<long long>((view.width + 1) / 2) * ((view.height + 1) / 2)
                                             : static_cast<long long>(view.width) * view.height;
      EXPECT_EQ(r.PrepareShading(view), ShadeLanesFor(first_pass, software)) << rate << " " << width;
      EXPECT_EQ(r.Render(view, ShadeDevice::kGpu).counts.shade_lanes, ShadeLanesFor(first_pass, software))
          << rate << " " << width;
    }
    EXPECT_EQ(r.Render(View(), ShadeDevice::kCpu).counts.shade_lanes, 0);
  }
  RenderOptions told;
  told.voxel_resolution = 64;
  told.shade_lanes = 2;
  TripleProductRenderer r(SphereAndBox(), glm::dmat4(1.0), told);
  r.SetLighting(SunnySky());
  EXPECT_EQ(r.PrepareShading(View()), 2);
  EXPECT_EQ(r.Render(View(), ShadeDevice::kGpu).counts.shade_lanes, 2);
}

// render_counts.comp's 64-bit sums: a frame's triples can pass 2³² (1280×720 samples × a few
// thousand each), so the low words must carry into the high ones, across work groups too.
TEST_F(TripleProductRendererGL, CountSumsCarryPast32Bits) {
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

TEST_F(TripleProductRendererGL, SupersampledIsTheSamplesResolvedWithCyclesPixelFilter) {
  for (int k : {2, 3}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    TripleProductRenderer plain(SphereAndBox(), glm::dmat4(1.0), o);
    o.supersample = k;
    o.supersample_contrast = 0;
    TripleProductRenderer super(SphereAndBox(), glm::dmat4(1.0), o);
    plain.SetLighting(SunnySky());
    super.SetLighting(SunnySky());
    const int w = 48, h = 32;
    const RenderResult samples = plain.Render(View(k * w, k * h), ShadeDevice::kGpu);
    const RenderResult point = plain.Render(View(w, h), ShadeDevice::kGpu);
    const RenderResult gpu = super.Render(View(w, h), ShadeDevice::kGpu);
    const RenderResult cpu = super.Render(View(w, h), ShadeDevice::kCpu);
    RenderResult expected;
    detail::ResolveSupersampled(samples, k, w, h, &expected);
    ASSERT_TRUE(AllFinite(gpu.car) && AllFinite(gpu.shadow) && AllFinite(cpu.car));
    ASSERT_EQ(gpu.car.width, w);
    ASSERT_EQ(gpu.car_alpha.size(), static_cast<std::size_t>(w * h));
    double worst_car = 0, worst_alpha = 0, worst_shadow = 0, worst_cpu_alpha = 0;
    int edge = 0, point_edge = 0;
    double area = 0, point_area = 0;
    for (std::size_t i = 0; i < gpu.car_alpha.size(); ++i) {
      worst_alpha = std::max(worst_alpha, double(std::abs(gpu.car_alpha[i] - expected.car_alpha[i])));
      worst_cpu_alpha = std::max(worst_cpu_alpha, double(std::abs(gpu.car_alpha[i] - cpu.car_alpha[i])));
      for (int c = 0; c < 3; ++c) {
        const double e = expected.car.rgb[3 * i + c];
        worst_car = std::max(worst_car, std::abs(gpu.car.rgb[3 * i + c] - e) / std::max(1e-3, std::abs(e)));
        worst_shadow =
            std::max(worst_shadow, double(std::abs(gpu.shadow.rgb[3 * i + c] - expected.shadow.rgb[3 * i + c])));
      }
      edge += gpu.car_alpha[i] > 0.01f && gpu.car_alpha[i] < 0.99f;
      point_edge += point.car_alpha[i] > 0.f && point.car_alpha[i] < 1.f;
      area += gpu.car_alpha[i];
      point_area += point.car_alpha[i];
    }
    const Diff car = Compare(gpu.car, cpu.car, gpu.car_alpha);
    std::printf(
        "k = %d: GPU resolve vs CPU resolve of the same samples: car %.2e rel, alpha %.2e, shadow %.2e; "
        "CPU shading vs GPU mean %.4f p99 %.4f rel; %d edge pixels (point sampled %d), area %.1f vs %.1f px\n",
        k, worst_car, worst_alpha, worst_shadow, car.mean_rel, car.p99_rel, edge, point_edge, area, point_area);
    EXPECT_LT(worst_car, 1e-5) << k;
    EXPECT_LT(worst_alpha, 1e-6) << k;
    EXPECT_LT(worst_shadow, 1e-5) << k;
    EXPECT_LT(worst_cpu_alpha, 1e-6) << k;
    EXPECT_LT(car.mean_rel, 0.01) << k;
    EXPECT_LT(car.p99_rel, 0.05) << k;
    EXPECT_EQ(point_edge, 0) << k;
    EXPECT_GT(edge, 30) << k;
    EXPECT_NEAR(area, point_area, 0.03 * point_area) << k;
    EXPECT_EQ(gpu.counts.car_pixels, samples.counts.car_pixels) << "counts are per shaded sample";
    // More samples than the GPU's textures hold: a clear error, not a failed allocation. Where
    // the camera's own limit comes first (an NVIDIA H200's textures are 32768 wide: k = 2 never
    // gets there), that limit is the clear error, tested by HardCaseCameraSize... below.
    GLint max_size = 0;
    glGetIntegerv(GL_MAX_TEXTURE_SIZE, &max_size);
    if (max_size / k + 1 > PinholeCamera::kMaxSide) continue;
    try {
      super.Render(View(max_size / k + 1, 8), ShadeDevice::kGpu);
      ADD_FAILURE() << "no error for " << max_size / k + 1 << " px wide at k = " << k;
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("beyond the GPU's textures"), std::string::npos) << e.what();
    }
  }
}

// Adaptive supersampling (RenderOptions::supersample_contrast > 0, the default): the GPU shades
// every sample only of the pixels render_flag.comp flags, the sample nearest the centre elsewhere.
// Its output must be the fully sampled image's samples resolved with its own flags by the CPU
// reference; its flags must match the CPU path's (detail::FlagPixels); every pixel whose samples
// differ in coverage must be flagged; it must shade fewer samples than every pixel's and land
// close to the fully supersampled image.
TEST_F(TripleProductRendererGL, AdaptiveSupersamplingShadesThePixelsThatNeedIt) {
  for (int k : {2, 3}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    TripleProductRenderer plain(SphereAndBox(), glm::dmat4(1.0), o);
    o.supersample = k;
    TripleProductRenderer adaptive(SphereAndBox(), glm::dmat4(1.0), o);
    o.supersample_contrast = 0;
    TripleProductRenderer every(SphereAndBox(), glm::dmat4(1.0), o);
    for (auto* r : {&plain, &adaptive, &every}) r->SetLighting(SunnySky());
    const int w = kW, h = kH;
    const RenderResult samples = plain.Render(View(k * w, k * h), ShadeDevice::kGpu);
    const RenderResult gpu = adaptive.Render(View(w, h), ShadeDevice::kGpu);
    const RenderResult cpu = adaptive.Render(View(w, h), ShadeDevice::kCpu);
    const RenderResult full = every.Render(View(w, h), ShadeDevice::kGpu);
    ASSERT_EQ(gpu.sampled_fully.size(), static_cast<std::size_t>(w * h));
    ASSERT_EQ(cpu.sampled_fully.size(), gpu.sampled_fully.size());
    RenderResult expected;
    detail::ResolveSupersampled(samples, k, w, h, &expected, &gpu.sampled_fully);
    double worst = 0;
    int flagged = 0, flag_mismatch = 0, mixed_unflagged = 0;
    for (std::size_t i = 0; i < gpu.car_alpha.size(); ++i) {
      worst = std::max(worst, double(std::abs(gpu.car_alpha[i] - expected.car_alpha[i])));
      for (int c = 0; c < 3; ++c) {
        const double e = expected.car.rgb[3 * i + c];
        worst = std::max(worst, std::abs(gpu.car.rgb[3 * i + c] - e) / std::max(1e-3, std::abs(e)));
        worst = std::max(worst, double(std::abs(gpu.shadow.rgb[3 * i + c] - expected.shadow.rgb[3 * i + c])));
      }
      flagged += gpu.sampled_fully[i];
      flag_mismatch += gpu.sampled_fully[i] != cpu.sampled_fully[i];
      // Coverage differing among the pixel's own samples: an edge, which must be flagged.
      const int px = static_cast<int>(i) % w, py = static_cast<int>(i) / w;
      float lo = 1, hi = 0;
      for (int sy = 0; sy < k; ++sy)
        for (int sx = 0; sx < k; ++sx) {
          const float a = samples.car_alpha[static_cast<std::size_t>(py * k + sy) * (k * w) + px * k + sx];
          lo = std::min(lo, a);
          hi = std::max(hi, a);
        }
      mixed_unflagged += lo != hi && !gpu.sampled_fully[i];
    }
    const Diff to_full = Compare(gpu.car, full.car, full.car_alpha);
    const Diff to_cpu = Compare(gpu.car, cpu.car, gpu.car_alpha);
    std::printf(
        "k = %d: %d of %d pixels flagged (%d car samples shaded, %d with every sample); GPU vs the CPU resolve of "
        "the same samples %.2e; flags differing from the CPU path's %d; against every sample shaded: mean %.4f "
        "p99 %.4f rel; against the CPU path mean %.4f p99 %.4f\n",
        k, flagged, w * h, gpu.counts.car_pixels, full.counts.car_pixels, worst, flag_mismatch, to_full.mean_rel,
        to_full.p99_rel, to_cpu.mean_rel, to_cpu.p99_rel);
    EXPECT_LT(worst, 1e-5) << k;
    EXPECT_EQ(gpu.counts.pixels_sampled_fully, flagged) << k;
    EXPECT_EQ(mixed_unflagged, 0) << k;
    EXPECT_LE(flag_mismatch, w * h / 100) << k;
    EXPECT_GT(flagged, 0) << k;
    EXPECT_LT(gpu.counts.car_pixels, full.counts.car_pixels * 3 / 4) << k;
    EXPECT_LT(to_full.mean_rel, 0.01) << k;
    EXPECT_LT(to_cpu.mean_rel, 0.01) << k;
    EXPECT_LT(to_cpu.p99_rel, 0.05) << k;
  }
}

// Mean of the car layer's luminance over covered pixels.
double MeanCarLuma(const RenderResult& r) {
  double sum = 0;
  int n = 0;
  for (std::size_t i = 0; i < r.car_alpha.size(); ++i)
    if (r.car_alpha[i] > 0.5f) {
      sum += Luma(&r.car.rgb[3 * i]);
      ++n;
    }
  return n ? sum / n : 0;
}

scene::GltfScene LambertSphere() {
  scene::GltfScene s;
  s.materials = {Pbr("ball", {0.5f, 0.5f, 0.5f}, 0.f, 1.f)};
  s.primitives.push_back(SpherePrimitive({0, 1.0f, 0}, 0.5f, 0));
  odvr::testing::Finish(&s);
  return s;
}

TEST_F(TripleProductRendererGL, FurnaceLambertianSphereUnderConstantLight) {
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.materials = {ParseMaterialOverride("lambert:0.5,0.5,0.5")};
  TripleProductRenderer r(LambertSphere(), glm::dmat4(1.0), o);
  lighting::SgLighting light;
  light.constant = glm::vec3(2.0f);
  r.SetLighting(light);
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.0, 3.0}, {0, 1.0, 0}, 30, kW, kH);
  for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    const RenderResult res = r.Render(cam, device);
    // The diffuse lobe is the clamped cosine itself: albedo × L, exactly.
    const double expected = 0.5 * 2.0;
    double worst = 0, mean = 0;
    int n = 0;
    for (std::size_t i = 0; i < res.car_alpha.size(); ++i) {
      if (res.car_alpha[i] < 0.5f) continue;
      for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(res.car.rgb[3 * i + c] / expected - 1));
      mean += res.car.rgb[3 * i] / expected;
      ++n;
    }
    mean /= n;
    std::printf("%s furnace: %d px, mean %.4f of albedo x L, worst %.4f\n", device == ShadeDevice::kGpu ? "GPU" : "CPU",
                n, mean, worst);
    EXPECT_GT(n, 400);
    // A convex sphere sees the whole sky: what its cones lose to its own voxels (measured 0.5 %
    // at 64³ with the surface offset of 2 voxels; 23 % without it) is the cone tracer's error.
    EXPECT_LT(worst, 0.1);
    EXPECT_NEAR(mean, 1.0, 0.02);
  }
}

// The Monte-Carlo baseline (RenderOptions::monte_carlo_samples) in a furnace: a Lambertian sphere
// under a constant map reflects exactly albedo × L (an unbiased estimator's mean over the sphere,
// within its noise), and so does the SG renderer, whose diffuse lobe is the clamped cosine.
TEST_F(TripleProductRendererGL, MonteCarloShaderConvergesInAFurnace) {
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.0, 3.0}, {0, 1.0, 0}, 30, kW, kH);
  const sphere::EquirectImage map(64, 32, 2.f);
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.materials = {ParseMaterialOverride("lambert:0.5,0.5,0.5")};
  lighting::SgLighting light;
  light.constant = glm::vec3(2.0f);
  TripleProductRenderer sg(LambertSphere(), glm::dmat4(1.0), o);
  sg.SetLighting(light);
  const double sg_mean = MeanCarLuma(sg.Render(cam));
  o.monte_carlo_samples = 64;
  TripleProductRenderer mc(LambertSphere(), glm::dmat4(1.0), o);
  mc.SetLighting(light);
  EXPECT_THROW(mc.Render(cam), Error);  // no map yet
  mc.SetEnvironment(map);
  const RenderResult res = mc.Render(cam);
  EXPECT_THROW(mc.Render(cam, ShadeDevice::kCpu), Error);
  ASSERT_TRUE(AllFinite(res.car));
  double mean = 0, var = 0;
  int n = 0;
  for (std::size_t i = 0; i < res.car_alpha.size(); ++i)
    if (res.car_alpha[i] > 0.5f) {
      mean += res.car.rgb[3 * i];
      var += res.car.rgb[3 * i] * res.car.rgb[3 * i];
      ++n;
    }
  mean /= n;
  const double sd = std::sqrt(std::max(0.0, var / n - mean * mean));
  std::printf("MC furnace: %d px, mean %.4f (exact 1), per-pixel sd %.4f at 64 spp; SG / MC %.4f\n", n, mean, sd,
              sg_mean / mean);
  EXPECT_GT(n, 400);
  // The sphere's own voxels shadow a little of the grazing sky (0.5 % for the SG cones).
  EXPECT_NEAR(mean, 1.0, 0.02);
  EXPECT_GT(sd, 0.0);  // a real estimator: per-pixel noise, not a closed form
  EXPECT_LT(sd, 0.15);
  EXPECT_NEAR(sg_mean / mean, 1.0, 0.025);
}

TEST_F(TripleProductRendererGL, EmissiveMaterialAddsItsRadianceInEveryShader) {
  // A glTF emissive material (the demo car's lamps) adds its radiance to what the surface
  // reflects, unshadowed: in the dark a lamp reads its emission exactly (the SG shader, its CPU
  // reference and the Monte-Carlo shader), under light the difference an emissive sphere makes is
  // its emission; the box, not emissive, does not change. An override naming another material
  // leaves the lamp on; one naming the lamp replaces the whole material, emission included.
  scene::GltfScene lit = SphereAndBox();
  lit.materials[0].emissive_factor = glm::vec3(0.8f, 0.4f, 0.1f);
  lit.materials[0].emissive_strength = 2.5f;
  const glm::vec3 emission(2.0f, 1.0f, 0.25f);
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  // The box's gloss would show the lit lamp (the bounce's own test: SpecularBounceShowsAnEmissive…).
  o.specular_bounce = false;
  const auto expect_emission = [&](const RenderResult& r, const char* what, const RenderResult* base) {
    int sphere_px = 0, box_px = 0;
    double worst = 0;
    for (std::size_t i = 0; i < r.car_alpha.size(); ++i) {
      if (r.car_alpha[i] <= 0.5f) continue;
      const float* c = &r.car.rgb[3 * i];
      const float* b = base ? &base->car.rgb[3 * i] : nullptr;
      // The sphere is the material whose pixels moved by the emission (or, in the dark, lit at all).
      const bool on_sphere = base ? std::abs(c[0] - b[0] - emission.x) < 1e-3 : c[0] > 0.5f;
      for (int k = 0; k < 3; ++k)
        worst = std::max(worst, std::abs(double(c[k]) - (b ? b[k] : 0.0) - (on_sphere ? emission[k] : 0.0)));
      ++(on_sphere ? sphere_px : box_px);
    }
    std::printf("%s: %d sphere px, %d box px, worst |difference - emission| %.2e\n", what, sphere_px, box_px, worst);
    EXPECT_GT(sphere_px, 300) << what;
    EXPECT_GT(box_px, 300) << what;
    EXPECT_LT(worst, 1e-4) << what;
  };
  TripleProductRenderer dark(lit, glm::dmat4(1.0), o);
  dark.SetLighting(lighting::SgLighting{});
  expect_emission(dark.Render(View(), ShadeDevice::kGpu), "dark, SG shader", nullptr);
  expect_emission(dark.Render(View(), ShadeDevice::kCpu), "dark, CPU reference", nullptr);
  dark.SetMaterials({ParseMaterialOverride("plastic=lambert:0.5,0.5,0.5")});
  expect_emission(dark.Render(View(), ShadeDevice::kGpu), "dark, the box's BRDF overridden", nullptr);
  dark.SetMaterials({ParseMaterialOverride("paint=lambert:0.5,0.5,0.5")});
  const RenderResult off = dark.Render(View(), ShadeDevice::kGpu);
  EXPECT_TRUE(std::all_of(off.car.rgb.begin(), off.car.rgb.end(), [](float v) { return v == 0.f; }));
  RenderOptions mc_options = o;
  mc_options.monte_carlo_samples = 4;
  TripleProductRenderer mc(lit, glm::dmat4(1.0), mc_options);
  mc.SetLighting(lighting::SgLighting{});
  mc.SetEnvironment(sphere::EquirectImage(64, 32, 0.f));
  expect_emission(mc.Render(View()), "dark, Monte-Carlo shader", nullptr);

  TripleProductRenderer sunny(lit, glm::dmat4(1.0), o), plain(SphereAndBox(), glm::dmat4(1.0), o);
  sunny.SetLighting(SunnySky());
  plain.SetLighting(SunnySky());
  const RenderResult base_gpu = plain.Render(View(), ShadeDevice::kGpu);
  expect_emission(sunny.Render(View(), ShadeDevice::kGpu), "sunny, SG shader", &base_gpu);
  const RenderResult base_cpu = plain.Render(View(), ShadeDevice::kCpu);
  expect_emission(sunny.Render(View(), ShadeDevice::kCpu), "sunny, CPU reference", &base_cpu);
}

// RenderOptions::monte_carlo_exact_visibility: the Monte-Carlo shader's shadow rays against the
// triangles. Under a box floating 0.3 m up in a constant sky, the ground's shadow ratio is one
// minus the box's bottom face's form factor (a point below a parallel rectangle, in closed form);
// the exact rays must reach it within their noise, the voxel rays are printed beside for scale.
TEST_F(TripleProductRendererGL, MonteCarloExactVisibilityMatchesTheFormFactorUnderABox) {
  scene::GltfScene box;
  box.materials = {Pbr("body", {0.4f, 0.4f, 0.45f}, 0.f, 0.6f)};
  box.primitives.push_back(BoxPrimitive({-1.0f, 0.3f, -0.5f}, {1.0f, 1.2f, 0.5f}, 0));
  odvr::testing::Finish(&box);
  // Low, so that it sees the ground under the box.
  const PinholeCamera cam = PinholeCamera::LookAt({0.3, 0.12, 2.5}, {0, 0.05, 0}, 30, kW, kH);
  const sphere::EquirectImage map(64, 32, 1.f);
  lighting::SgLighting light;
  light.constant = glm::vec3(1.0f);
  // A point under a corner of an a × b rectangle at height c, parallel to the ground.
  const auto corner = [](double a, double b, double c) {
    const double x = a / c, y = b / c, sx = std::sqrt(1 + x * x), sy = std::sqrt(1 + y * y);
    return (x / sx * std::atan(y / sx) + y / sy * std::atan(x / sy)) / (2 * 3.14159265358979);
  };
  double error[2] = {0, 0};
  int n = 0;
  for (const bool exact : {true, false}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.monte_carlo_samples = 64;
    o.monte_carlo_exact_visibility = exact;
    TripleProductRenderer r(box, glm::dmat4(1.0), o);
    r.SetLighting(light);
    r.SetEnvironment(map);
    const RenderResult res = r.Render(cam);
    ASSERT_TRUE(AllFinite(res.shadow));
    double sum = 0, truth = 0;
    n = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * kW + x;
        if (res.ground_mask[i] < 0.5f || res.car_alpha[i] > 0.f) continue;
        const glm::dvec3 d = cam.Ray(x + 0.5, y + 0.5);
        const glm::dvec3 q = cam.position - (cam.position.y / d.y) * d;
        // Well under the box (a few voxels from its edges, where the voxels' blur is not the point).
        if (std::abs(q.x) > 0.8 || std::abs(q.z) > 0.35) continue;
        const double f = corner(1 - q.x, 0.5 - q.z, 0.3) + corner(1 + q.x, 0.5 - q.z, 0.3) +
                         corner(1 - q.x, 0.5 + q.z, 0.3) + corner(1 + q.x, 0.5 + q.z, 0.3);
        sum += Luma(&res.shadow.rgb[3 * i]);
        truth += 1 - f;
        ++n;
      }
    ASSERT_GT(n, 30) << "too few ground pixels under the box";
    error[exact ? 0 : 1] = (sum - truth) / n;
    std::printf("ground under the box, %s visibility: mean ratio %.4f, form factor %.4f (%d px)\n",
                exact ? "exact" : "voxel", sum / n, truth / n, n);
  }
  EXPECT_LT(std::abs(error[0]), 0.015);
}

TEST_F(TripleProductRendererGL, ShadowUnderTheCarAndNoneWithoutIt) {
  RenderOptions o;
  o.voxel_resolution = 64;
  scene::GltfScene car;
  car.materials = {Pbr("body", {0.4f, 0.4f, 0.45f}, 0.f, 0.6f)};
  car.primitives.push_back(BoxPrimitive({-1.0f, 0.3f, -0.5f}, {1.0f, 1.2f, 0.5f}, 0));  // floats 0.3 m up
  odvr::testing::Finish(&car);
  const PinholeCamera cam = PinholeCamera::LookAt({0, 4.0, 6.0}, {0, 0.3, 0}, 45, kW, kH);
  // Overcast (no peak): the ground under the car loses most of its sky.
  lighting::SgLighting sky = FullLighting(3, SkyRadiance);
  TripleProductRenderer r(car, glm::dmat4(1.0), o);
  r.SetLighting(sky);
  const RenderResult res = r.Render(cam);
  // The ground point under the car's centre, and one 5 m to the side.
  const auto pixel_of = [&](const glm::dvec3& p) {
    const glm::dvec3 c = glm::transpose(cam.world_from_camera) * (p - cam.position);
    const int x = static_cast<int>(cam.focal_px() * c.x / c.z + 0.5 * kW);
    const int y = static_cast<int>(cam.focal_px() * c.y / c.z + 0.5 * kH);
    return static_cast<std::size_t>(y) * kW + x;
  };
  // 15 cm in front of the box's long side and beside its end, against 5 m away.
  const std::size_t front = pixel_of({0, 0, 0.65}), beside = pixel_of({1.15, 0, 0}), far = pixel_of({-4.5, 0, 2.5});
  for (std::size_t i : {front, beside, far}) ASSERT_GT(res.ground_mask[i], 0.5f);
  const double near_ratio = std::max(Luma(&res.shadow.rgb[3 * front]), Luma(&res.shadow.rgb[3 * beside]));
  const double far_ratio = Luma(&res.shadow.rgb[3 * far]);
  double min_ratio = 1;
  for (std::size_t i = 0; i < res.ground_mask.size(); ++i)
    if (res.ground_mask[i] > 0.5f) min_ratio = std::min(min_ratio, Luma(&res.shadow.rgb[3 * i]));
  std::printf("overcast shadow ratio: darkest %.3f, beside the car %.3f, 5 m away %.3f\n", min_ratio, near_ratio,
              far_ratio);
  EXPECT_LT(min_ratio, 0.6);
  EXPECT_LT(near_ratio, far_ratio - 0.1);
  EXPECT_GT(far_ratio, 0.9);

  // A sun straight above: the ground under the box is in its shadow, the ground beside it not.
  lighting::SgLighting sunny = sky;
  sunny.peaks.push_back({{0, 1, 0}, 5000.0, glm::vec3(3000.f)});
  r.SetLighting(sunny);
  const RenderResult sun = r.Render(cam);
  const std::size_t under_edge = pixel_of({0.0, 0, 0.45});  // visible under the box's front edge? then shadowed
  if (sun.ground_mask[under_edge] > 0.5f) {
    EXPECT_LT(Luma(&sun.shadow.rgb[3 * under_edge]), 0.3);
  }
  EXPECT_GT(Luma(&sun.shadow.rgb[3 * pixel_of({0.0, 0, 0.9})]), 0.85);  // 0.4 m beside the box's shadow

  // No car: the same ground is unshadowed everywhere, and the composite is the background.
  scene::GltfScene empty;
  TripleProductRenderer bare(empty, glm::dmat4(1.0), o);
  bare.SetLighting(sunny);
  sphere::EquirectImage env(64, 32);
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 64; ++x)
      for (int c = 0; c < 3; ++c) env.at(x, y)[c] = 0.1f + 0.01f * static_cast<float>(x + y + c);
  bare.SetEnvironment(env);
  const RenderResult none = bare.Render(cam);
  EXPECT_EQ(none.counts.car_pixels, 0);
  double max_dev = 0, max_bg = 0;
  for (std::size_t i = 0; i < none.shadow.rgb.size(); ++i) {
    max_dev = std::max(max_dev, std::abs(none.shadow.rgb[i] - 1.0));
    max_bg = std::max(max_bg, static_cast<double>(std::abs(none.composite.rgb[i] - none.background.rgb[i])));
  }
  EXPECT_EQ(max_dev, 0.0);
  EXPECT_EQ(max_bg, 0.0);
  EXPECT_TRUE(AllFinite(none.background));
  EXPECT_GT(*std::min_element(none.background.rgb.begin(), none.background.rgb.end()), 0.09f);
}

// A grey box floating 0.3 m above the ground, and a camera low beside it that sees its
// underside, front and side: the faces that see the ground it shadows.
scene::GltfScene FloatingBox() {
  scene::GltfScene car;
  car.materials = {Pbr("body", {0.5f, 0.5f, 0.5f}, 0.f, 0.9f)};
  car.primitives.push_back(BoxPrimitive({-1.0f, 0.3f, -0.5f}, {1.0f, 1.2f, 0.5f}, 0));
  odvr::testing::Finish(&car);
  return car;
}
PinholeCamera FloatingBoxCamera() { return PinholeCamera::LookAt({-2.5, 0.2, 3.0}, {0, 0.6, 0}, 45, kW, kH); }

// RenderOptions::ground_shadows_bounce: light from below the horizon (the ground's bounce) is
// darkened where the car shadows the ground. A box floating 0.3 m up under a constant light from
// every direction: its faces that see the ground under and beside it get less with the term
// than without (the underside most), the GPU agrees with the CPU reference, and a light with
// nothing below the horizon is not touched by it.
TEST_F(TripleProductRendererGL, CarSeesItsShadowOnTheGround) {
  const scene::GltfScene car = FloatingBox();
  const PinholeCamera cam = FloatingBoxCamera();
  lighting::SgLighting everywhere;
  everywhere.constant = glm::vec3(1.f);
  RenderOptions on;
  on.voxel_resolution = 64;
  RenderOptions off = on;
  off.ground_shadows_bounce = false;
  TripleProductRenderer r_on(car, glm::dmat4(1.0), on), r_off(car, glm::dmat4(1.0), off);
  r_on.SetLighting(everywhere);
  r_off.SetLighting(everywhere);
  const RenderResult gpu = r_on.Render(cam, ShadeDevice::kGpu), cpu = r_on.Render(cam, ShadeDevice::kCpu);
  const RenderResult without = r_off.Render(cam, ShadeDevice::kGpu);
  ASSERT_GT(gpu.counts.car_pixels, 300);
  const Diff d = Compare(gpu.car, cpu.car, gpu.car_alpha);
  std::printf("ground's shadow in its bounce: car mean %.4f with, %.4f without; GPU vs CPU mean %.4f p99 %.4f rel\n",
              MeanCarLuma(gpu), MeanCarLuma(without), d.mean_rel, d.p99_rel);
  EXPECT_LT(MeanCarLuma(gpu), 0.99 * MeanCarLuma(without));  // measured 2.9 % darker
  EXPECT_LT(d.mean_rel, 0.01);
  EXPECT_LT(d.p99_rel, 0.05);

  // Nothing below the horizon: the term changes nothing.
  lighting::SgLighting above;
  above.peaks.push_back({glm::normalize(glm::dvec3(0.3, 1, 0.2)), 200.0, glm::vec3(5.f)});
  r_on.SetLighting(above);
  r_off.SetLighting(above);
  const Diff same =
      Compare(r_on.Render(cam, ShadeDevice::kGpu).car, r_off.Render(cam, ShadeDevice::kGpu).car, gpu.car_alpha);
  EXPECT_LT(same.max_rel, 1e-5);
}

// What the car's shadow takes off the ground's bounce is the ground's own radiance (the
// lighting's cosine-weighted mean below the horizon), not the share of every lighting SG that
// the cones below the horizon see: a broad light (λ 3) at 30° elevation adds 62 % to the box
// and 9.4 % to the ground's radiance, so the loss grows by that 9.4 %. Scaling each SG's share
// in those cones by the ground's lit fraction (this renderer until it was measured against
// Cycles) took 13.2 % more (measured).
TEST_F(TripleProductRendererGL, CarsShadowTakesTheGroundsRadianceOffItsBounce) {
  const scene::GltfScene car = FloatingBox();
  const PinholeCamera cam = FloatingBoxCamera();
  RenderOptions on;
  on.voxel_resolution = 64;
  on.peak_cones = false;  // the light is seen through the lobes' cones, as every SRBF is
  RenderOptions off = on;
  off.ground_shadows_bounce = false;
  TripleProductRenderer r_on(car, glm::dmat4(1.0), on), r_off(car, glm::dmat4(1.0), off);
  const auto loss = [&](const lighting::SgLighting& l, RenderResult* shaded) {
    r_on.SetLighting(l);
    r_off.SetLighting(l);
    *shaded = r_on.Render(cam, ShadeDevice::kGpu);
    const RenderResult without = r_off.Render(cam, ShadeDevice::kGpu);
    return MeanCarLuma(without) - MeanCarLuma(*shaded);
  };
  lighting::SgLighting sky;
  sky.constant = glm::vec3(1.f);
  lighting::SgLighting broad = sky;  // a broad light above the horizon
  const double elevation = 30 * 3.14159265358979323846 / 180;
  const lighting::RgbSg light{glm::dvec3(-std::cos(elevation) * 0.6, std::sin(elevation), std::cos(elevation) * 0.8),
                              3.0, glm::vec3(2.f)};
  broad.peaks.push_back(light);
  // The ground's radiance under each, by quadrature: (1/π) ∫ below the horizon L |w·y|.
  double spill = 0;
  const int n = 400;
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < 2 * n; ++j) {
      const double y = -(i + 0.5) / n, phi = (j + 0.5) * 3.14159265358979323846 / n;
      const double r = std::sqrt(1 - y * y);
      const glm::dvec3 w(r * std::cos(phi), y, r * std::sin(phi));
      spill += lighting::Evaluate({light.axis, light.lambda, 2.0}, w) * -y * (1.0 / n) * (3.14159265358979323846 / n);
    }
  const double ground_ratio = 1.0 + spill / 3.14159265358979323846;
  RenderResult sky_image, broad_image;
  const double sky_loss = loss(sky, &sky_image), broad_loss = loss(broad, &broad_image);
  std::printf(
      "ground's shadow in its bounce: loss %.5f under the sky, %.5f with the broad light (ratio %.4f, the "
      "ground's radiance %.4f); car %.4f → %.4f\n",
      sky_loss, broad_loss, broad_loss / sky_loss, ground_ratio, MeanCarLuma(sky_image), MeanCarLuma(broad_image));
  ASSERT_GT(sky_loss, 0.0);
  EXPECT_GT(MeanCarLuma(broad_image), 1.3 * MeanCarLuma(sky_image));  // the light reaches the box
  EXPECT_NEAR(broad_loss / sky_loss, ground_ratio, 0.01);
  const Diff d = Compare(broad_image.car, r_on.Render(cam, ShadeDevice::kCpu).car, broad_image.car_alpha);
  EXPECT_LT(d.mean_rel, 0.01);
  EXPECT_LT(d.p99_rel, 0.05);
}

// RenderOptions::ground_lit_map_texels: the ground's lit fraction read from a grid stands for
// the traces it replaces. A box 1.2 m tall under a sun at 35° (a traced peak with 60 % of the
// ground's irradiance): outside the grid every trace sees nothing (the layout's claim, which lets
// the shader skip them), inside the bilinear read is close to the trace at the same point, and a
// sun on the horizon widens the grid to the whole catcher.
TEST(GroundLitMap, StandsForTheTracesItReplaces) {
  const auto spec = visibility::VoxelGridSpec::Covering({-2, 0.2, -1}, {2, 1.4, 1}, 64);
  visibility::VoxelGrid grid(spec);
  grid.Voxelize(odvr::testing::BoxMesh({-2.f, 0.2f, -1.f}, {2.f, 1.4f, 1.f}));
  grid.BuildMips();
  detail::PreparedLighting l;
  const double elevation = 35 * 3.14159265358979323846 / 180;
  l.peaks.push_back(
      {glm::dvec3(std::cos(elevation) * 0.8, std::sin(elevation), std::cos(elevation) * 0.6), 2000.0, glm::vec3(1.f)});
  l.ground_peak_share = {0.6};
  const auto trace = [&](const glm::dvec3& o, const glm::dvec3& axis, double a) {
    return grid.TraceCone({glm::vec3(o), glm::vec3(axis), static_cast<float>(a)});
  };
  const auto lit = [&](double x, double z) {
    return detail::GroundLitFraction(glm::dvec3(x, 0, z), l, true, kGroundLitHalfAngle, visibility::kMaxConeHalfAngle,
                                     trace);
  };
  const detail::GroundLitMapLayout m = detail::GroundLitMapLayoutFor(spec, l, true, {0, 0}, 30, 128);
  ASSERT_GT(m.width, 8);
  ASSERT_LE(std::max(m.width, m.height), 128);
  std::vector<float> texels(m.texels());
  for (std::size_t t = 0; t < texels.size(); ++t)
    texels[t] =
        static_cast<float>(lit(m.origin.x + static_cast<double>(t % static_cast<std::size_t>(m.width)) * m.spacing,
                               m.origin.y + static_cast<double>(t / static_cast<std::size_t>(m.width)) * m.spacing));
  double outside_min = 1, sum_abs = 0, max_abs = 0;
  int inside = 0, outside = 0, shadowed = 0;
  for (int i = 0; i < 120; ++i)
    for (int j = 0; j < 120; ++j) {
      const double x = -9 + 18 * (i + 0.37) / 120, z = -9 + 18 * (j + 0.61) / 120;
      const double traced = lit(x, z);
      const double fx = (x - m.origin.x) / m.spacing, fz = (z - m.origin.y) / m.spacing;
      if (fx < 0 || fz < 0 || fx >= m.width - 1 || fz >= m.height - 1) {
        outside_min = std::min(outside_min, traced);
        ++outside;
        continue;
      }
      const double e = std::abs(detail::SampleGroundLitMap(m, texels, x, z) - traced);
      sum_abs += e;
      max_abs = std::max(max_abs, e);
      ++inside;
      shadowed += traced < 0.9;
    }
  std::printf(
      "ground lit grid %dx%d at %.3f m: %d points inside (%d shadowed), |grid - trace| mean %.4f max %.3f; "
      "%d outside, lowest trace there %.4f\n",
      m.width, m.height, m.spacing, inside, shadowed, sum_abs / inside, max_abs, outside, outside_min);
  EXPECT_GT(shadowed, 500);
  EXPECT_GT(outside, 2000);
  EXPECT_EQ(outside_min, 1.0);
  EXPECT_LT(sum_abs / inside, 0.01);
  EXPECT_LT(max_abs, 0.3);

  // A sun 3° up (sunset.exr's): its shadow reaches the catcher's edge, so the texels are the
  // catcher's width over 128, far wider than a voxel; near the box the read blurs the shadow's edge.
  detail::PreparedLighting low = l;
  const double low_elevation = 3 * 3.14159265358979323846 / 180;
  low.peaks[0].axis = glm::dvec3(std::cos(low_elevation) * 0.8, std::sin(low_elevation), std::cos(low_elevation) * 0.6);
  const auto low_lit = [&](double x, double z) {
    return detail::GroundLitFraction(glm::dvec3(x, 0, z), low, true, kGroundLitHalfAngle, visibility::kMaxConeHalfAngle,
                                     trace);
  };
  const detail::GroundLitMapLayout lm = detail::GroundLitMapLayoutFor(spec, low, true, {0, 0}, 30, 128);
  std::vector<float> low_texels(lm.texels());
  for (std::size_t t = 0; t < low_texels.size(); ++t)
    low_texels[t] = static_cast<float>(
        low_lit(lm.origin.x + static_cast<double>(t % static_cast<std::size_t>(lm.width)) * lm.spacing,
                lm.origin.y + static_cast<double>(t / static_cast<std::size_t>(lm.width)) * lm.spacing));
  double low_sum = 0;
  int low_n = 0;
  for (int i = 0; i < 100; ++i)
    for (int j = 0; j < 100; ++j) {
      const double x = -4 + 8 * (i + 0.37) / 100, z = -4 + 8 * (j + 0.61) / 100;
      low_sum += std::abs(detail::SampleGroundLitMap(lm, low_texels, x, z) - low_lit(x, z));
      ++low_n;
    }
  std::printf("sun 3 deg up: grid %dx%d at %.3f m, |grid - trace| mean %.4f within 4 m of the box\n", lm.width,
              lm.height, lm.spacing, low_sum / low_n);
  EXPECT_LE(std::max(lm.width, lm.height), 128);
  EXPECT_LT(low_sum / low_n, 0.02);  // measured 0.0091

  // Without peak cones the grid is the cube's footprint; a sun on the horizon reaches anywhere.
  const detail::GroundLitMapLayout up_only = detail::GroundLitMapLayoutFor(spec, l, false, {0, 0}, 30, 128);
  EXPECT_LT(up_only.width, m.width);
  EXPECT_NEAR(up_only.spacing, spec.voxel_size, 1e-12);
  detail::PreparedLighting horizon = l;
  horizon.peaks[0].axis = glm::dvec3(1, 0, 0);
  const detail::GroundLitMapLayout wide = detail::GroundLitMapLayoutFor(spec, horizon, true, {0, 0}, 30, 128);
  EXPECT_LE(wide.origin.x, -30.0);
  EXPECT_GE(wide.origin.x + (wide.width - 1) * wide.spacing, 30.0);
  EXPECT_LE(std::max(wide.width, wide.height), 128);
}

// The renderer with the grid against the traces per cone, and its GPU path against the CPU
// reference with the grid: the floating box under a sky and a sun whose shadow it sees below it.
TEST_F(TripleProductRendererGL, GroundLitMapShadesAsTheTracesDo) {
  const scene::GltfScene car = FloatingBox();
  const PinholeCamera cam = FloatingBoxCamera();
  lighting::SgLighting l;
  l.constant = glm::vec3(0.5f);
  const double elevation = 40 * 3.14159265358979323846 / 180;
  l.peaks.push_back({glm::dvec3(-std::cos(elevation) * 0.6, std::sin(elevation), std::cos(elevation) * 0.8), 800.0,
                     glm::vec3(400.f)});
  RenderOptions grid;
  grid.voxel_resolution = 64;
  RenderOptions traced = grid, off = grid;
  traced.ground_lit_map_texels = 0;
  off.ground_shadows_bounce = false;
  TripleProductRenderer r_grid(car, glm::dmat4(1.0), grid), r_traced(car, glm::dmat4(1.0), traced),
      r_off(car, glm::dmat4(1.0), off);
  for (auto* r : {&r_grid, &r_traced, &r_off}) r->SetLighting(l);
  const RenderResult with_grid = r_grid.Render(cam, ShadeDevice::kGpu), cpu = r_grid.Render(cam, ShadeDevice::kCpu);
  const RenderResult with_traces = r_traced.Render(cam, ShadeDevice::kGpu),
                     without = r_off.Render(cam, ShadeDevice::kGpu);
  ASSERT_GT(with_grid.counts.car_pixels, 300);
  const double loss_grid = MeanCarLuma(without) - MeanCarLuma(with_grid),
               loss_traced = MeanCarLuma(without) - MeanCarLuma(with_traces);
  const Diff d = Compare(with_grid.car, with_traces.car, with_grid.car_alpha),
             g = Compare(with_grid.car, cpu.car, with_grid.car_alpha);
  std::printf(
      "ground's shadow in the bounce: loss %.5f read from the grid, %.5f traced per cone; car grid vs traces "
      "mean %.5f p99 %.4f rel; GPU vs CPU (grid) mean %.5f p99 %.4f\n",
      loss_grid, loss_traced, d.mean_rel, d.p99_rel, g.mean_rel, g.p99_rel);
  ASSERT_GT(loss_traced, 0.0);
  EXPECT_NEAR(loss_grid / loss_traced, 1.0, 0.05);
  EXPECT_LT(d.mean_rel, 0.005);
  EXPECT_LT(g.mean_rel, 0.01);
  EXPECT_LT(g.p99_rel, 0.05);
}

// RenderOptions::shading_rate 2: one pixel of each smooth 2×2 block shaded, the rest filled
// between shaded pixels (render_fill.comp). On the glossy sphere and box under a sunny sky it
// shades fewer pixels, stays close to shading every pixel, and the GPU's flags and fill are the
// CPU reference's (detail::FlagPixels with the neighbours' pixels, detail::FillHalfRate). At an
// odd size the blocks the edges cut are shaded whole, and the GPU still agrees with the CPU.
TEST_F(TripleProductRendererGL, HalfRateShadingFillsOnlySmoothBlocks) {
  RenderOptions full;
  full.voxel_resolution = 64;
  RenderOptions half = full;
  half.shading_rate = 2;
  TripleProductRenderer r_full(SphereAndBox(), glm::dmat4(1.0), full), r_half(SphereAndBox(), glm::dmat4(1.0), half);
  r_full.SetLighting(SunnySky());
  r_half.SetLighting(SunnySky());
  const RenderResult every = r_full.Render(View(), ShadeDevice::kGpu);
  const RenderResult gpu = r_half.Render(View(), ShadeDevice::kGpu), cpu = r_half.Render(View(), ShadeDevice::kCpu);
  const int pixels = kW * kH;
  const Diff to_full = Compare(gpu.car, every.car, every.car_alpha),
             to_cpu = Compare(gpu.car, cpu.car, every.car_alpha);
  double shadow_diff = 0;
  for (std::size_t i = 0; i < gpu.shadow.rgb.size(); ++i)
    shadow_diff = std::max(shadow_diff, static_cast<double>(std::abs(gpu.shadow.rgb[i] - every.shadow.rgb[i])));
  std::size_t flags_differ = 0, filled = 0;
  for (std::size_t i = 0; i < gpu.sampled_fully.size(); ++i) {
    flags_differ += gpu.sampled_fully[i] != cpu.sampled_fully[i];
    filled += gpu.sampled_fully[i] == 0;
  }
  std::printf(
      "half rate: %d of %d pixels shaded (%zu filled); car to every pixel shaded mean %.4f p99 %.4f rel, "
      "shadow |d| max %.4f; GPU vs CPU mean %.4f, shaded flags differ at %zu pixels\n",
      gpu.counts.pixels_sampled_fully, pixels, filled, to_full.mean_rel, to_full.p99_rel, shadow_diff, to_cpu.mean_rel,
      flags_differ);
  ASSERT_EQ(gpu.sampled_fully.size(), static_cast<std::size_t>(pixels));
  EXPECT_EQ(gpu.counts.pixels_sampled_fully, pixels - static_cast<int>(filled));
  EXPECT_LT(gpu.counts.pixels_sampled_fully, pixels * 6 / 10);
  EXPECT_EQ(gpu.counts.car_pixels, every.counts.car_pixels);
  // Measured 0.0006 / 0.014 and 0.0014; a fill that copies each block's shaded pixel (blocky)
  // reads 0.0021 / 0.058 and 0.0032.
  EXPECT_LT(to_full.mean_rel, 0.0012);
  EXPECT_LT(to_full.p99_rel, 0.03);
  EXPECT_LT(to_cpu.mean_rel, 0.0025);
  EXPECT_LT(flags_differ, static_cast<std::size_t>(pixels / 100));

  const PinholeCamera odd = View(kW + 1, kH + 1);
  const RenderResult odd_gpu = r_half.Render(odd, ShadeDevice::kGpu), odd_cpu = r_half.Render(odd, ShadeDevice::kCpu);
  const Diff odd_diff = Compare(odd_gpu.car, odd_cpu.car, odd_cpu.car_alpha);
  int edge_filled = 0;
  for (int y = 0; y < kH + 1; ++y)
    for (int x = 0; x < kW + 1; ++x)
      if ((x == kW || y == kH) && !odd_gpu.sampled_fully[static_cast<std::size_t>(y) * (kW + 1) + x]) ++edge_filled;
  std::printf("odd size %dx%d: %d pixels shaded, GPU vs CPU mean %.4f, edge pixels filled %d\n", kW + 1, kH + 1,
              odd_gpu.counts.pixels_sampled_fully, odd_diff.mean_rel, edge_filled);
  EXPECT_EQ(edge_filled, 0);
  EXPECT_LT(odd_diff.mean_rel, 0.0025);  // measured 0.0011 (the blocky fill: 0.0035)
  EXPECT_EQ(odd_gpu.counts.pixels_sampled_fully,
            static_cast<int>(std::count(odd_gpu.sampled_fully.begin(), odd_gpu.sampled_fully.end(), 1)));
}

TEST_F(TripleProductRendererGL, MoreLevelsAndMoreConesConverge) {
  // Levels: a glossy sphere under a sky with detail on every level; the converged answer uses all
  // five. Leaving levels out loses that detail, so the error to it shrinks as levels are added.
  scene::GltfScene s;
  s.materials = {Pbr("chrome", {0.9f, 0.9f, 0.9f}, 1.f, 0.15f)};
  s.primitives.push_back(SpherePrimitive({0, 1.0f, 0}, 0.5f, 0));
  odvr::testing::Finish(&s);
  const lighting::SgLighting sky = FullLighting(5, SkyRadiance, 1.0f);
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.3, 3.0}, {0, 1.0, 0}, 30, 64, 48);
  std::vector<RenderResult> by_level;
  for (int levels = 1; levels <= 5; ++levels) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.lighting_levels = levels;
    o.ground = false;
    TripleProductRenderer r(s, glm::dmat4(1.0), o);
    r.SetLighting(sky);
    by_level.push_back(r.Render(cam));
  }
  double previous = 1e9;
  for (int l = 0; l < 4; ++l) {
    const Diff d = Compare(by_level[static_cast<std::size_t>(l)].car, by_level[4].car, by_level[4].car_alpha);
    std::printf("levels %d: mean relative difference to 5 levels %.4f\n", l + 1, d.mean_rel);
    EXPECT_LT(d.mean_rel, previous);
    previous = d.mean_rel;
  }

  // Cones: a diffuse sphere beside a tall wall, lit by a sky; the converged answer is 37 cones.
  scene::GltfScene walled = LambertSphere();
  walled.materials.push_back(Pbr("wall", {0.5f, 0.5f, 0.5f}, 0.f, 1.f));
  walled.primitives.push_back(BoxPrimitive({0.55f, 0.f, -2.f}, {0.75f, 3.f, 2.f}, 1));
  odvr::testing::Finish(&walled);
  std::vector<RenderResult> by_rings;
  for (int rings = 0; rings <= 3; ++rings) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.cone_rings = rings;
    o.ground = false;
    TripleProductRenderer r(walled, glm::dmat4(1.0), o);
    r.SetLighting(FullLighting(3, SkyRadiance));
    by_rings.push_back(r.Render(PinholeCamera::LookAt({-1.5, 1.4, 2.8}, {0.2, 1.0, 0}, 35, 64, 48)));
  }
  std::vector<float> sphere_only(by_rings[3].car_alpha.size(), 0.f);
  int on_sphere = 0;
  for (std::size_t i = 0; i < sphere_only.size(); ++i) {
    // The sphere's pixels: those the wall-less render covers as well.
    sphere_only[i] = by_rings[3].car_alpha[i];
    on_sphere += sphere_only[i] > 0.5f;
  }
  ASSERT_GT(on_sphere, 300);
  const Diff one = Compare(by_rings[0].car, by_rings[3].car, sphere_only);
  const Diff seven = Compare(by_rings[1].car, by_rings[3].car, sphere_only);
  const Diff nineteen = Compare(by_rings[2].car, by_rings[3].car, sphere_only);
  std::printf("cones 1 / 7 / 19: mean relative difference to 37 cones %.4f / %.4f / %.4f\n", one.mean_rel,
              seven.mean_rel, nineteen.mean_rel);
  EXPECT_LT(seven.mean_rel, one.mean_rel);
  EXPECT_LT(nineteen.mean_rel, one.mean_rel);
  // One cone cannot tell which side of a lobe the wall is on; 7 already can.
  EXPECT_GT(one.mean_rel, 2 * seven.mean_rel);
}

// Renders `model` on both devices under the sunny sky and checks every layer is finite and
// in range; returns the GPU result.
RenderResult RenderBothFinite(const scene::GltfScene& model, const RenderOptions& o, const lighting::SgLighting& light,
                              const PinholeCamera& cam, const char* what) {
  TripleProductRenderer r(model, glm::dmat4(1.0), o);
  r.SetLighting(light);
  RenderResult gpu = r.Render(cam, ShadeDevice::kGpu);
  const RenderResult cpu = r.Render(cam, ShadeDevice::kCpu);
  for (const RenderResult* res : {static_cast<const RenderResult*>(&gpu), &cpu}) {
    EXPECT_TRUE(AllFinite(res->car)) << what;
    EXPECT_TRUE(AllFinite(res->shadow)) << what;
    EXPECT_TRUE(AllFinite(res->composite)) << what;
    EXPECT_GE(*std::min_element(res->car.rgb.begin(), res->car.rgb.end()), 0.f) << what;
    for (float v : res->shadow.rgb) {
      EXPECT_GE(v, 0.f) << what;
      EXPECT_LE(v, 1.f) << what;
    }
  }
  const Diff d = Compare(gpu.car, cpu.car, gpu.car_alpha, 1e-2);
  std::printf("%s: %d car px, GPU vs CPU mean relative %.4f\n", what, d.pixels, d.mean_rel);
  EXPECT_LT(d.mean_rel, 0.03) << what;
  return gpu;
}

TEST_F(TripleProductRendererGL, HardCasePhongMirror) {
  RenderOptions o;
  o.voxel_resolution = 64;
  o.materials = {ParseMaterialOverride("phong:1,1,1,10000")};
  const RenderResult res = RenderBothFinite(LambertSphere(), o, SunnySky(5), View(), "Phong n=10000");
  EXPECT_GT(res.counts.car_pixels, 300);
  // A mirror's lobe is one cone and narrow: it needs the deepest levels and few SGs.
  EXPECT_NEAR(res.counts.cones_per_car_pixel, 2.0, 1e-6);  // the lobe's cone and the peak's
  EXPECT_GT(MeanCarLuma(res), 0.05);
}

TEST_F(TripleProductRendererGL, HardCaseCarInsideAPeaksCone) {
  // A "peak" as wide as a quarter of the sky: its cone is clamped to the widest the tracer
  // takes (74.5°) and holds the whole car from every ground point near it.
  lighting::SgLighting light;
  light.constant = glm::vec3(0.1f);
  light.peaks.push_back({glm::normalize(glm::dvec3(0.2, 1, 0.1)), 1.5, glm::vec3(4.f)});
  RenderOptions o;
  o.voxel_resolution = 64;
  const RenderResult res = RenderBothFinite(SphereAndBox(), o, light, View(), "wide peak");
  double darkest = 1;
  for (std::size_t i = 0; i < res.ground_mask.size(); ++i)
    if (res.ground_mask[i] > 0.5f) darkest = std::min(darkest, Luma(&res.shadow.rgb[3 * i]));
  std::printf("wide peak: darkest shadow ratio %.3f\n", darkest);
  EXPECT_LT(darkest, 0.8);
}

TEST_F(TripleProductRendererGL, HardCaseDegenerateGeometry) {
  scene::GltfScene s = SphereAndBox();
  scene::ScenePrimitive bad;
  bad.name = "degenerate";
  bad.material = 0;
  // Zero-area triangles (a repeated vertex, three collinear points) and zero, NaN and inf normals.
  bad.positions = {{-0.8f, 0.5f, 0.6f}, {-0.8f, 0.5f, 0.6f}, {-0.6f, 0.9f, 0.6f},
                   {-0.9f, 0.2f, 0.7f}, {-0.7f, 0.4f, 0.7f}, {-0.5f, 0.6f, 0.7f},
                   {-1.2f, 0.2f, 0.8f}, {-0.6f, 0.2f, 0.8f}, {-0.9f, 0.9f, 0.8f}};
  const float nan = std::numeric_limits<float>::quiet_NaN(), inf = std::numeric_limits<float>::infinity();
  bad.normals = {{0, 0, 0}, {nan, 0, 1}, {inf, 0, 0},     {0, 0, 0},     {0, 0, 0},
                 {0, 0, 0}, {0, 0, 0},   {nan, nan, nan}, {0, 0, 1e-30f}};
  bad.indices = {0, 1, 2, 3, 4, 5, 6, 7, 8};
  s.primitives.push_back(bad);
  odvr::testing::Finish(&s);
  RenderOptions o;
  o.voxel_resolution = 64;
  const RenderResult res = RenderBothFinite(s, o, SunnySky(), View(), "degenerate triangles and normals");
  EXPECT_GT(res.counts.car_pixels, 500);
}

TEST_F(TripleProductRendererGL, HardCaseEmptySceneRendersTheBackground) {
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

// A player's background: one panorama turned by its own rotation (not the lighting's), sampled by
// the GPU composite as the CPU path samples it; without the model, the composite is that
// background alone.
TEST_F(TripleProductRendererGL, BackgroundEquirectHasItsOwnRotationAndCanStandAlone) {
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

TEST_F(TripleProductRendererGL, HardCaseModelFarLargerThanTheVoxelVolume) {
  // A 2 km slab under a 1 m sphere: the volume covers the slab, its 64 voxels are 31 m each, so
  // the sphere is far below a voxel. Nothing may break: every layer finite, the sphere lit.
  scene::GltfScene s = LambertSphere();
  s.materials.push_back(Pbr("slab", {0.3f, 0.3f, 0.3f}, 0.f, 1.f));
  s.primitives.push_back(BoxPrimitive({-1000.f, -2.f, -1000.f}, {1000.f, -1.f, 1000.f}, 1));
  odvr::testing::Finish(&s);
  RenderOptions o;
  o.voxel_resolution = 64;
  const RenderResult res = RenderBothFinite(s, o, SunnySky(), View(), "2 km slab");
  EXPECT_GT(MeanCarLuma(res), 0.05);
}

TEST_F(TripleProductRendererGL, HardCaseEveryParameterAtItsBound) {
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.2, 3.0}, {0, 1.0, 0}, 30, 48, 32);
  for (const char* m :
       {"mr:1,1,1,1,0", "mr:0,0,0,0,1", "mr:1,1,1,0,0", "phong:1,1,1,0", "phong:1,1,1,100000", "blinn:1,1,1,100000",
        "blinn:0,0,0,0", "ward:1,1,1,1", "ward:1,1,1,0.000001", "ct:1,1,1,0.000001", "ct:1,1,1,1,beckmann",
        "ct:0,0,0,1", "lambert:1,1,1+phong:1,1,1,100000", "1,0,0", "0,1,100000"}) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.cone_rings = 2;
    o.materials = {ParseMaterialOverride(m)};
    RenderBothFinite(LambertSphere(), o, SunnySky(5), cam, m);
  }
}

}  // namespace
}  // namespace odvr::render
