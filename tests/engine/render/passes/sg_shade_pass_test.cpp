// The SG shading pass (render_shade.comp) of TripleProductRenderer on small synthetic scenes:
// - against the CPU reference on the same G-buffer (96×64), for every lobe mode and lane count;
// - a furnace: a Lambertian sphere under a constant environment reads albedo × radiance times
//   the integral of brdf.h's clamped-cosine SG over the sphere (3.395 instead of π, +8.1 %);
// - reflection normals, the specular bounce, the ambient bounce (a white furnace with a recess),
//   emission;
// - more lighting levels and more cones move the result towards the converged one.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <glm/geometric.hpp>
#include <numbers>
#include <vector>

#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/material/brdf.h"
#include "engine/sphere/equirect.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_measures.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using odvr::testing::AllFinite;
using odvr::testing::BoxPrimitive;
using odvr::testing::Compare;
using odvr::testing::Diff;
using odvr::testing::FullLighting;
using odvr::testing::kH;
using odvr::testing::kW;
using odvr::testing::LambertSphere;
using odvr::testing::Luma;
using odvr::testing::MeanOnPlane;
using odvr::testing::Pbr;
using odvr::testing::SkyRadiance;
using odvr::testing::SphereAndBox;
using odvr::testing::SpherePrimitive;
using odvr::testing::SunnySky;
using odvr::testing::View;
using SgShadePassGL = odvr::testing::GlTest;

TEST_F(SgShadePassGL, GpuMatchesCpuReference) {
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
TEST_F(SgShadePassGL, DepthPerLobeDropsTheLevelsALobeCannotShow) {
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

TEST_F(SgShadePassGL, GpuMatchesCpuReferenceForEveryLobeMode) {
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

// RenderOptions::shade_lanes: 2 or 4 invocations per pixel, each shading every L-th lobe, give
// the one-invocation picture (float sums in another order) and the same counts, with a peak
// (its cone and integrals summed across lanes), plainly and with adaptive supersampling (the
// listed samples' pass).
TEST_F(SgShadePassGL, ShadeLanesGiveTheSamePictureAndCounts) {
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

// Each render says the lanes it shaded with: the rule's pick for its first pass on this device
// (the pixels at rate 1, the 2×2 blocks at rate 2), what it was told otherwise, 0 on the CPU.
TEST_F(SgShadePassGL, ShadeLanesArePickedPerRender) {
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

// RenderOptions::valid_reflection_normals: a mirror slab whose top's vertex normals lean 30° away
// from a camera 10° above it. The view mirrored about those normals dives 32° below the top, into
// the slab; tilted toward the face just enough, it leaves at a grazing height and sees a light
// 3° above the horizon beyond the slab. The GPU and the CPU shade the same G-buffer.
TEST_F(SgShadePassGL, ValidReflectionNormalsKeepTheMirroredViewAboveTheFace) {
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
    o.materials = {MaterialOverride{"", {material::Phong{glm::dvec3(1), 1e4}}}};
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

// A floor from floor_lo to (2, 0, 2) and, with `wall`, an emissive box from wall_lo to wall_hi
// sending `radiance`: the specular bounce's scenes (the floor's paint is overridden there).
scene::GltfScene MirrorFloorAndWall(float radiance, glm::vec3 floor_lo, glm::vec3 wall_lo, glm::vec3 wall_hi,
                                    bool wall) {
  scene::GltfScene s;
  s.materials = {Pbr("floor", {0.5f, 0.5f, 0.5f}, 0.f, 0.5f), Pbr("wall", {0.f, 0.f, 0.f}, 0.f, 1.f)};
  s.materials[1].emissive_factor = glm::vec3(1.f);
  s.materials[1].emissive_strength = radiance;
  s.primitives.push_back(BoxPrimitive(floor_lo, {2.f, 0.f, 2.f}, 0));
  if (wall) s.primitives.push_back(BoxPrimitive(wall_lo, wall_hi, 1));
  odvr::testing::Finish(&s);
  return s;
}

// RenderOptions::specular_bounce: a mirror floor (Phong n = 10 000, reflectance 0.5) in front of
// an emissive wall, in the dark. Where the floor mirrors the wall its cone is blocked, and without
// the bounce the floor reads black; with it, the floor's lost light is the wall's radiance, which
// the G-buffer march finds: the same floor under an open sky of that radiance reads the same. GPU
// and CPU alike.
TEST_F(SgShadePassGL, SpecularBounceShowsAnEmissiveWallInAMirrorFloor) {
  const float radiance = 3.f;
  const auto scene = [&](bool wall) {
    return MirrorFloorAndWall(radiance, {-2.f, -0.05f, -1.2f}, {-2.f, 0.f, -1.2f}, {2.f, 1.5f, -1.f}, wall);
  };
  const PinholeCamera view = PinholeCamera::LookAt({0.0, 1.0, 3.0}, {0.0, 0.3, -0.5}, 50, 96, 64);
  const auto floor_mean = [&](bool wall, bool bounce, ShadeDevice device, int lanes = 1) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    o.specular_bounce = bounce;
    o.shade_lanes = lanes;
    o.materials = {MaterialOverride{"floor", {material::Phong{glm::dvec3(0.5), 1e4}}}};
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

// The specular bounce's ray against the triangles (with RenderOptions::exact_peak_shadows) finds
// what the camera does not see: the mirror floor of the test above, the emissive wall now high
// and far, above the picture's top edge. The floor mirrors it as it mirrors an open sky of its
// radiance, on both devices; the G-buffer march alone (the peaks' cones) finds nothing to mirror.
TEST_F(SgShadePassGL, SpecularBounceShowsAWallOutOfThePicture) {
  const float radiance = 3.f;
  const auto scene = [&](bool wall) {
    return MirrorFloorAndWall(radiance, {-2.f, -0.05f, -3.4f}, {-3.f, 0.8f, -3.4f}, {3.f, 3.f, -3.2f}, wall);
  };
  // Looking down at the floor's middle: the picture's top ray passes under the wall.
  const PinholeCamera view = PinholeCamera::LookAt({0.0, 1.0, 3.0}, {0.0, 0.0, 0.0}, 30, 96, 64);
  const auto floor_mean = [&](bool wall, bool exact, ShadeDevice device, int* wall_pixels) {
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    o.exact_peak_shadows = exact;
    o.materials = {MaterialOverride{"floor", {material::Phong{glm::dvec3(0.5), 1e4}}}};
    TripleProductRenderer r(scene(wall), glm::dmat4(1.0), o);
    lighting::SgLighting light;
    if (!wall) light.constant = glm::vec3(radiance);
    r.SetLighting(light);
    const RenderResult res = r.Render(view, device);
    *wall_pixels = 0;  // pixels brighter than the floor can be: the wall itself
    for (std::size_t i = 0; i < res.car_alpha.size(); ++i)
      if (res.car_alpha[i] > 0.5f && res.car.rgb[3 * i] > 2.f) ++*wall_pixels;
    return MeanOnPlane(view, res, 0.0, -0.4, 0.4, 0.3);
  };
  for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    int seen = 0, unused = 0;
    const double sky = floor_mean(false, true, device, &unused), rays = floor_mean(true, true, device, &seen),
                 march = floor_mean(true, false, device, &unused);
    std::printf("%s: the floor mirroring an open sky %.4f, the hidden wall by rays %.4f, by the march %.4f\n",
                device == ShadeDevice::kGpu ? "GPU" : "CPU", sky, rays, march);
    EXPECT_EQ(seen, 0);  // the wall is out of the picture
    EXPECT_GT(sky, 0.3 * radiance);
    EXPECT_NEAR(rays / sky, 1.0, 0.1);
    EXPECT_LT(march, 0.02 * sky);
  }
}

TEST_F(SgShadePassGL, FurnaceLambertianSphereUnderConstantLight) {
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.materials = {MaterialOverride{"", {material::Lambertian{glm::dvec3(0.5)}}}};
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

// A white furnace with a recess: an L of a floor slab and a wall, albedo 1, under a constant
// sky. Light is conserved, so every surface reads the sky's radiance, the inner corner too; the
// ambient bounce gives back what the cones lose to the car itself, without it the corner is dark.
TEST_F(SgShadePassGL, AmbientBounceKeepsAWhiteFurnaceCornerAtTheSkysRadiance) {
  scene::GltfScene corner;
  corner.materials = {Pbr("white", {1.f, 1.f, 1.f}, 0.f, 1.f)};
  corner.primitives.push_back(BoxPrimitive({-1.0f, 0.5f, -1.0f}, {1.0f, 0.7f, 1.0f}, 0));   // floor slab
  corner.primitives.push_back(BoxPrimitive({-1.0f, 0.7f, -1.0f}, {1.0f, 2.2f, -0.8f}, 0));  // wall at its back
  odvr::testing::Finish(&corner);
  lighting::SgLighting light;
  light.constant = glm::vec3(2.0f);
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.9, 2.4}, {0, 0.8, -0.7}, 40, kW, kH);
  for (bool bounce : {true, false}) {
    double means[2] = {0, 0};
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    o.ambient_bounce = bounce;
    o.materials = {MaterialOverride{"", {material::Lambertian{glm::dvec3(1.0)}}}};
    TripleProductRenderer r(corner, glm::dmat4(1.0), o);
    r.SetLighting(light);
    for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
      const RenderResult res = r.Render(cam, device);
      ASSERT_TRUE(AllFinite(res.car));
      // Each car pixel's radiance over the sky's: 1 everywhere for a white furnace.
      std::vector<double> ratio;
      for (std::size_t i = 0; i < res.car_alpha.size(); ++i)
        if (res.car_alpha[i] > 0.5f) ratio.push_back(res.car.rgb[3 * i + 1] / 2.0);
      ASSERT_GT(ratio.size(), 1000u);
      std::sort(ratio.begin(), ratio.end());
      double mean = 0;
      for (double v : ratio) mean += v / static_cast<double>(ratio.size());
      const double p5 = ratio[ratio.size() / 20];  // the recess: the darkest 5 %
      std::printf("%s, ambient bounce %s: mean %.4f of L, 5th percentile %.4f, over %zu px\n",
                  device == ShadeDevice::kGpu ? "GPU" : "CPU", bounce ? "on" : "off", mean, p5, ratio.size());
      if (bounce) {
        EXPECT_NEAR(mean, 1.0, 0.01);
        EXPECT_GT(p5, 0.98) << "the recess reads the sky's radiance";
      } else {
        EXPECT_LT(p5, 0.8) << "without the bounce the cones lose the corner's light to the car";
      }
      means[device == ShadeDevice::kGpu ? 0 : 1] = mean;
    }
    EXPECT_NEAR(means[0], means[1], 2e-3) << "GPU and CPU reference";
  }
}

TEST_F(SgShadePassGL, EmissiveMaterialAddsItsRadianceInEveryShader) {
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
  dark.SetMaterials({MaterialOverride{"plastic", {material::Lambertian{glm::dvec3(0.5)}}}});
  expect_emission(dark.Render(View(), ShadeDevice::kGpu), "dark, the box's BRDF overridden", nullptr);
  dark.SetMaterials({MaterialOverride{"paint", {material::Lambertian{glm::dvec3(0.5)}}}});
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

// glTF's emission is the factor × strength × the emissive texture, sRGB-decoded: a texture that
// is mostly black (ToyCar's lamps) must not let the factor light the whole body. One texel
// (188, 128, 64) decodes to (0.5029, 0.2158, 0.0513); in the dark the sphere reads twice that in
// the SG shader, its CPU reference and the Monte-Carlo shader alike.
TEST_F(SgShadePassGL, EmissiveTextureScalesTheEmissionInEveryShader) {
  scene::GltfScene lit = SphereAndBox();
  scene::TextureImage texel;
  texel.name = "lamp texel";
  texel.width = texel.height = 1;
  texel.rgba = {188, 128, 64, 255};
  lit.images.push_back(texel);
  lit.materials[0].emissive_factor = glm::vec3(1.f);
  lit.materials[0].emissive_strength = 2.f;
  lit.materials[0].emissive_texture.image = 0;
  const glm::dvec3 expected = 2.0 * glm::dvec3(0.50289, 0.21586, 0.05127);
  RenderOptions o;
  o.voxel_resolution = 64;
  o.ground = false;
  o.specular_bounce = false;
  const auto sphere_mean = [&](const RenderResult& r, const char* what) {
    glm::dvec3 sum(0);
    int n = 0;
    for (std::size_t i = 0; i < r.car_alpha.size(); ++i) {
      if (r.car_alpha[i] <= 0.5f || !(r.car.rgb[3 * i] > 0.1f)) continue;
      sum += glm::dvec3(r.car.rgb[3 * i], r.car.rgb[3 * i + 1], r.car.rgb[3 * i + 2]);
      ++n;
    }
    const glm::dvec3 mean = sum / static_cast<double>(std::max(n, 1));
    std::printf("%s: %d sphere px, mean emission (%.4f, %.4f, %.4f)\n", what, n, mean.x, mean.y, mean.z);
    EXPECT_GT(n, 300) << what;
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mean[c], expected[c], 2e-3) << what << " channel " << c;
  };
  TripleProductRenderer dark(lit, glm::dmat4(1.0), o);
  dark.SetLighting(lighting::SgLighting{});
  sphere_mean(dark.Render(View(), ShadeDevice::kGpu), "SG shader");
  sphere_mean(dark.Render(View(), ShadeDevice::kCpu), "CPU reference");
  RenderOptions mc_options = o;
  mc_options.monte_carlo_samples = 4;
  TripleProductRenderer mc(lit, glm::dmat4(1.0), mc_options);
  mc.SetLighting(lighting::SgLighting{});
  mc.SetEnvironment(sphere::EquirectImage(64, 32, 0.f));
  sphere_mean(mc.Render(View()), "Monte-Carlo shader");
}

// KHR_materials_transmission (PbrMaterial::transmission): a fully transmissive dielectric keeps
// its reflection and loses its diffuse layer, so a green glass sphere renders as a black one
// would; half transmissive lies between. GPU and CPU alike.
TEST_F(SgShadePassGL, TransmissionTakesTheDiffuseLayerAndKeepsTheReflection) {
  const auto render = [&](glm::vec3 base, float transmission, ShadeDevice device) {
    scene::GltfScene s = SphereAndBox();
    s.materials[0].base_color_factor = glm::vec4(base, 1.f);
    s.materials[0].metallic_factor = 0.f;
    s.materials[0].roughness_factor = 0.1f;
    s.materials[0].transmission = transmission;
    RenderOptions o;
    o.voxel_resolution = 64;
    o.ground = false;
    TripleProductRenderer r(s, glm::dmat4(1.0), o);
    r.SetLighting(SunnySky());
    return r.Render(View(), device);
  };
  const glm::vec3 green(0.3f, 0.8f, 0.3f);
  for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    const RenderResult glass = render(green, 1.f, device), black = render(glm::vec3(0.f), 0.f, device);
    const RenderResult half = render(green, 0.5f, device), opaque = render(green, 0.f, device);
    double worst = 0, g_half = 0, g_opaque = 0, g_glass = 0;
    for (std::size_t i = 0; i < glass.car_alpha.size(); ++i) {
      if (glass.car_alpha[i] <= 0.5f) continue;
      for (int c = 0; c < 3; ++c)
        worst = std::max(worst, std::abs(double(glass.car.rgb[3 * i + c]) - black.car.rgb[3 * i + c]));
      g_glass += glass.car.rgb[3 * i + 1];
      g_half += half.car.rgb[3 * i + 1];
      g_opaque += opaque.car.rgb[3 * i + 1];
    }
    std::printf("%s: glass vs black worst %.2e; green channel sums glass %.2f, half %.2f, opaque %.2f\n",
                device == ShadeDevice::kGpu ? "GPU" : "CPU", worst, g_glass, g_half, g_opaque);
    EXPECT_LT(worst, 1e-5);
    EXPECT_GT(g_half, g_glass * 1.2);
    EXPECT_GT(g_opaque, g_half * 1.2);
  }
}

TEST_F(SgShadePassGL, MoreLevelsAndMoreConesConverge) {
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

}  // namespace
}  // namespace odvr::render
