// The Monte-Carlo baseline (render_mc.comp): it converges in a furnace, and its exact visibility
// matches the analytic form factor under a box.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

#include "core/error.h"
#include "engine/material/brdf.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_measures.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using odvr::testing::AllFinite;
using odvr::testing::BoxPrimitive;
using odvr::testing::kH;
using odvr::testing::kW;
using odvr::testing::LambertSphere;
using odvr::testing::Luma;
using odvr::testing::MeanCarLuma;
using odvr::testing::Pbr;
using MonteCarloShadePassGL = odvr::testing::GlTest;

// The Monte-Carlo baseline (RenderOptions::monte_carlo_samples) in a furnace: a Lambertian sphere
// under a constant map reflects exactly albedo × L (an unbiased estimator's mean over the sphere,
// within its noise), and so does the SG renderer, whose diffuse lobe is the clamped cosine.
TEST_F(MonteCarloShadePassGL, MonteCarloShaderConvergesInAFurnace) {
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.0, 3.0}, {0, 1.0, 0}, 30, kW, kH);
  const sphere::EquirectImage map(64, 32, 2.f);
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.materials = {MaterialOverride{"", {material::Lambertian{glm::dvec3(0.5)}}}};
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

// A sheen (material::Sheen, KHR_materials_sheen's) alone on a sphere in a furnace: the SG shader's
// and the CPU reference's lobe (the albedo table's clamped cosine) against the Monte-Carlo
// shader, which evaluates the Charlie BRDF itself; all three within the estimator's noise, and
// brighter at the silhouette (grazing views) than at the centre, as a sheen is.
TEST_F(MonteCarloShadePassGL, SheenLobeMatchesTheMonteCarloOfItsBrdf) {
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.0, 3.0}, {0, 1.0, 0}, 30, kW, kH);
  const scene::GltfScene sphere = LambertSphere();
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.materials = {MaterialOverride{"", {material::Sheen{glm::dvec3(1.0, 0.5, 0.25), 0.5}}}};
  lighting::SgLighting light;
  light.constant = glm::vec3(2.0f);
  TripleProductRenderer sg(sphere, glm::dmat4(1.0), o);
  sg.SetLighting(light);
  const RenderResult gpu = sg.Render(cam), cpu = sg.Render(cam, ShadeDevice::kCpu);
  o.monte_carlo_samples = 256;
  TripleProductRenderer mc(sphere, glm::dmat4(1.0), o);
  mc.SetLighting(light);
  mc.SetEnvironment(sphere::EquirectImage(64, 32, 2.f));
  const RenderResult ref = mc.Render(cam);
  ASSERT_TRUE(AllFinite(gpu.car) && AllFinite(cpu.car) && AllFinite(ref.car));
  // The red channel over the sphere's centre and its outer ring (the pixels' distance from the
  // sphere's centre in the image, relative to its radius there).
  const auto ring_means = [&](const RenderResult& r, double* centre, double* rim) {
    double c = 0, e = 0, cx = 0, cy = 0;
    int nc = 0, ne = 0, n = 0;
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x)
        if (r.car_alpha[static_cast<std::size_t>(y) * kW + x] > 0.5f) cx += x, cy += y, ++n;
    cx /= n;
    cy /= n;
    const double radius = std::sqrt(n / kPi);
    for (int y = 0; y < kH; ++y)
      for (int x = 0; x < kW; ++x) {
        const std::size_t i = static_cast<std::size_t>(y) * kW + x;
        if (r.car_alpha[i] <= 0.5f) continue;
        const double d = std::hypot(x - cx, y - cy) / radius;
        if (d < 0.5) c += r.car.rgb[3 * i], ++nc;
        if (d > 0.8) e += r.car.rgb[3 * i], ++ne;
      }
    *centre = c / std::max(nc, 1);
    *rim = e / std::max(ne, 1);
  };
  double gc, ge, cc, ce, mc_c, mc_e;
  ring_means(gpu, &gc, &ge);
  ring_means(cpu, &cc, &ce);
  ring_means(ref, &mc_c, &mc_e);
  std::printf("sheen furnace, red: centre SG %.4f CPU %.4f MC %.4f; rim SG %.4f CPU %.4f MC %.4f\n", gc, cc, mc_c, ge,
              ce, mc_e);
  EXPECT_NEAR(gc, cc, 1e-3 * gc);
  EXPECT_NEAR(ge, ce, 1e-3 * ge);
  // 256 samples of a smooth integrand, averaged over hundreds of pixels: a 2 % gap is the lobe's.
  EXPECT_NEAR(gc / mc_c, 1.0, 0.02);
  EXPECT_NEAR(ge / mc_e, 1.0, 0.02);
  EXPECT_GT(mc_e, 2.0 * mc_c) << "a sheen is brightest at grazing views";
}

// RenderOptions::monte_carlo_exact_visibility: the Monte-Carlo shader's shadow rays against the
// triangles. Under a box floating 0.3 m up in a constant sky, the ground's shadow ratio is one
// minus the box's bottom face's form factor (a point below a parallel rectangle, in closed form);
// the exact rays must reach it within their noise, the voxel rays are printed beside for scale.
TEST_F(MonteCarloShadePassGL, MonteCarloExactVisibilityMatchesTheFormFactorUnderABox) {
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

}  // namespace
}  // namespace odvr::render
