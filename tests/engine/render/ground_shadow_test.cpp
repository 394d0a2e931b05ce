// The shadow catcher: darker under the car than far from it, absent without the car; the car's
// shadow on it darkening the ground's bounce that the car sees; the ground-lit map standing for
// the traces it replaces.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <vector>

#include "engine/lighting/sg.h"
#include "engine/render/triple_product_internal.h"
#include "engine/sphere/equirect.h"
#include "engine/visibility/voxel_grid.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_measures.h"
#include "tests/engine/render/render_test_scenes.h"
#include "tests/engine/visibility/test_meshes.h"

namespace odvr::render {
namespace {

using odvr::testing::AllFinite;
using odvr::testing::BoxPrimitive;
using odvr::testing::Compare;
using odvr::testing::Diff;
using odvr::testing::FloatingBox;
using odvr::testing::FloatingBoxCamera;
using odvr::testing::FullLighting;
using odvr::testing::kH;
using odvr::testing::kW;
using odvr::testing::Luma;
using odvr::testing::MeanCarLuma;
using odvr::testing::Pbr;
using odvr::testing::SkyRadiance;
using GroundShadowGL = odvr::testing::GlTest;

TEST_F(GroundShadowGL, ShadowUnderTheCarAndNoneWithoutIt) {
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

// RenderOptions::ground_shadows_bounce: light from below the horizon (the ground's bounce) is
// darkened where the car shadows the ground. A box floating 0.3 m up under a constant light from
// every direction: its faces that see the ground under and beside it get less with the term
// than without (the underside most), the GPU agrees with the CPU reference, and a light with
// nothing below the horizon is not touched by it.
TEST_F(GroundShadowGL, CarSeesItsShadowOnTheGround) {
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
TEST_F(GroundShadowGL, CarsShadowTakesTheGroundsRadianceOffItsBounce) {
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
TEST(GroundShadow, TheGroundLitMapStandsForTheTracesItReplaces) {
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
TEST_F(GroundShadowGL, GroundLitMapShadesAsTheTracesDo) {
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

}  // namespace
}  // namespace odvr::render
