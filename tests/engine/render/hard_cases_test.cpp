// The renderer's hard cases, each rendered on both devices, finite, in range and agreeing: Phong
// n = 10⁴, a car inside a peak's cone, zero-area triangles and degenerate normals, a model far
// larger than the voxel volume, a toy-sized model, every material parameter at its bound.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>
#include <glm/geometric.hpp>
#include <limits>
#include <utility>
#include <vector>

#include "core/error.h"
#include "engine/material/brdf.h"
#include "tests/engine/gl/gl_test_context.h"
#include "tests/engine/render/render_test_measures.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::render {
namespace {

using odvr::testing::BoxPrimitive;
using odvr::testing::kH;
using odvr::testing::kW;
using odvr::testing::LambertSphere;
using odvr::testing::Luma;
using odvr::testing::MeanCarLuma;
using odvr::testing::Pbr;
using odvr::testing::RenderBothFinite;
using odvr::testing::SphereAndBox;
using odvr::testing::SunnySky;
using odvr::testing::View;
using HardCasesGL = odvr::testing::GlTest;

TEST_F(HardCasesGL, HardCasePhongMirror) {
  RenderOptions o;
  o.voxel_resolution = 64;
  o.materials = {MaterialOverride{"", {material::Phong{glm::dvec3(1), 1e4}}}};
  const RenderResult res = RenderBothFinite(LambertSphere(), o, SunnySky(5), View(), "Phong n=10000");
  EXPECT_GT(res.counts.car_pixels, 300);
  // A mirror's lobe is one cone and narrow: it needs the deepest levels and few SGs.
  EXPECT_NEAR(res.counts.cones_per_car_pixel, 2.0, 1e-6);  // the lobe's cone and the peak's
  EXPECT_GT(MeanCarLuma(res), 0.05);
}

TEST_F(HardCasesGL, HardCaseCarInsideAPeaksCone) {
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

TEST_F(HardCasesGL, HardCaseDegenerateGeometry) {
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

TEST_F(HardCasesGL, HardCaseModelFarLargerThanTheVoxelVolume) {
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

// A model in centimetres renders as one in metres: the scene scaled by 1/50 about the origin (the
// ground stays y = 0), its camera with it, gives the same picture on both devices. Every length
// the renderer steps or offsets by is a fraction of the voxels, so only float rounding differs.
TEST_F(HardCasesGL, HardCaseAToySizedModelRendersAsACarSizedOne) {
  const double scale = 0.02;
  const render::PinholeCamera car_view = View();
  const render::PinholeCamera toy_view = render::PinholeCamera::LookAt(
      scale * glm::dvec3(-1.2, 1.6, 3.2), scale * glm::dvec3(0.2, 0.4, 0), car_view.vfov_deg, kW, kH);
  RenderOptions o;
  o.voxel_resolution = 64;
  TripleProductRenderer car(SphereAndBox(), glm::dmat4(1.0), o);
  TripleProductRenderer toy(SphereAndBox(), glm::dmat4(glm::dmat3(scale)), o);
  car.SetLighting(SunnySky());
  toy.SetLighting(SunnySky());
  for (ShadeDevice device : {ShadeDevice::kGpu, ShadeDevice::kCpu}) {
    const RenderResult a = car.Render(car_view, device), b = toy.Render(toy_view, device);
    const odvr::testing::Diff car_diff = odvr::testing::Compare(b.car, a.car, a.car_alpha, 1e-2);
    const odvr::testing::Diff shadow_diff = odvr::testing::Compare(b.shadow, a.shadow, a.ground_mask, 1e-2);
    std::printf("toy vs car size (%s): car mean relative %.5f over %d px, shadow %.5f\n",
                device == ShadeDevice::kGpu ? "GPU" : "CPU", car_diff.mean_rel, car_diff.pixels, shadow_diff.mean_rel);
    EXPECT_GT(car_diff.pixels, 1000);
    EXPECT_LT(car_diff.mean_rel, 3e-3);
    EXPECT_LT(shadow_diff.mean_rel, 3e-3);
  }
}

TEST_F(HardCasesGL, HardCaseEveryParameterAtItsBound) {
  using material::BlinnPhong, material::CookTorrance, material::Lambertian, material::MetallicRoughness, material::Ndf,
      material::Phong, material::Ward;
  const glm::dvec3 one(1), zero(0);
  const std::vector<std::pair<const char*, std::vector<material::Brdf>>> bounds = {
      {"mr white metal, mirror", {MetallicRoughness{one, 1, 0}}},
      {"mr black dielectric, rough", {MetallicRoughness{zero, 0, 1}}},
      {"mr white dielectric, mirror", {MetallicRoughness{one, 0, 0}}},
      {"phong n = 0", {Phong{one, 0}}},
      {"phong n = 1e5", {Phong{one, 1e5}}},
      {"blinn s = 1e5", {BlinnPhong{one, 1e5}}},
      {"blinn black, s = 0", {BlinnPhong{zero, 0}}},
      {"ward alpha = 1", {Ward{one, 1, 1}}},
      {"ward alpha = 1e-6", {Ward{one, 1e-6, 1e-6}}},
      {"ct alpha = 1e-6", {CookTorrance{one, 1e-6, Ndf::kGgx}}},
      {"ct beckmann alpha = 1", {CookTorrance{one, 1, Ndf::kBeckmann}}},
      {"ct black, alpha = 1", {CookTorrance{zero, 1, Ndf::kGgx}}},
      {"lambert white + phong n = 1e5", {Lambertian{one}, Phong{one, 1e5}}},
      {"kd 1, ks 0, n 0", {Lambertian{one}, Phong{zero, 0}}},
      {"kd 0, ks 1, n 1e5", {Lambertian{zero}, Phong{one, 1e5}}}};
  const PinholeCamera cam = PinholeCamera::LookAt({0, 1.2, 3.0}, {0, 1.0, 0}, 30, 48, 32);
  for (const auto& [what, brdfs] : bounds) {
    for (const auto& brdf : brdfs) EXPECT_NO_THROW(material::CheckBrdf(brdf)) << what;
    RenderOptions o;
    o.voxel_resolution = 64;
    o.cone_rings = 2;
    o.materials = {MaterialOverride{"", brdfs}};
    RenderBothFinite(LambertSphere(), o, SunnySky(5), cam, what);
  }
}

// An override out of its ranges reaches the renderer only through code: it is refused there as
// the command line refuses it, not rendered into NaN.
TEST_F(HardCasesGL, HardCaseAnOverrideOutOfItsRangeIsRefused) {
  RenderOptions o;
  o.voxel_resolution = 64;
  o.materials = {MaterialOverride{"", {material::CookTorrance{glm::dvec3(1), 0.0}}}};
  EXPECT_THROW(TripleProductRenderer(LambertSphere(), glm::dmat4(1.0), o), Error);
  TripleProductRenderer r(LambertSphere(), glm::dmat4(1.0), RenderOptions{});
  EXPECT_THROW(r.SetMaterials({MaterialOverride{"ball", {material::Phong{glm::dvec3(1), -1.0}}}}), Error);
}

}  // namespace
}  // namespace odvr::render
