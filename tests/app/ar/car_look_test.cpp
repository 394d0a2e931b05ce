// The player's car panel edits a CarLook (app/ar/car_look.h); the scene renders what it says. Each
// control must change the car as drawn, and nothing but the car and its shadow.
#include "app/ar/car_look.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <string>
#include <variant>

#include "app/ar/augmented_scene.h"
#include "core/error.h"
#include "engine/gl/context.h"
#include "engine/scene/gltf_scene.h"
#include "tests/engine/render/render_test_scenes.h"

namespace odvr::app {
namespace {

namespace fs = std::filesystem;
const fs::path kDemo = fs::path(ODVR_SOURCE_DIR) / "media" / "demo";

TEST(CarLook, MaterialOverridesFollowTheModelAndItsParameters) {
  CarLook look;
  EXPECT_TRUE(MaterialOverrides(look).empty()) << "glTF: the model's own materials";
  look.model = CarLook::Model::kPhong;
  look.colour = {0.5f, 0.25f, 0.125f};
  look.ks = 0.2;
  look.phong_n = 80;
  auto o = MaterialOverrides(look);
  ASSERT_EQ(o.size(), 1u);
  EXPECT_TRUE(o[0].material.empty()) << "every material of the car";
  ASSERT_EQ(o[0].brdfs.size(), 2u);
  const auto& kd = std::get<material::Lambertian>(o[0].brdfs[0]);
  EXPECT_NEAR(kd.albedo.x, 0.8 * 0.5, 1e-7);
  EXPECT_NEAR(kd.albedo.z, 0.8 * 0.125, 1e-7);
  const auto& phong = std::get<material::Phong>(o[0].brdfs[1]);
  EXPECT_DOUBLE_EQ(phong.ks.y, 0.2);
  EXPECT_DOUBLE_EQ(phong.exponent, 80);

  look.model = CarLook::Model::kCookTorrance;
  look.roughness = 0.4;
  look.fresnel_f0 = 0.5;
  o = MaterialOverrides(look);
  const auto& ct = std::get<material::CookTorrance>(o[0].brdfs[1]);
  EXPECT_DOUBLE_EQ(ct.alpha, 0.4);
  EXPECT_DOUBLE_EQ(ct.f0.x, 0.2 * 0.5);

  for (auto bad :
       {+[](CarLook& l) { l.ks = 1.5; }, +[](CarLook& l) { l.roughness = 0; }, +[](CarLook& l) { l.fresnel_f0 = -0.1; },
        +[](CarLook& l) { l.colour[1] = 2; }, +[](CarLook& l) { l.phong_n = -1; }}) {
    CarLook l = look;
    bad(l);
    EXPECT_THROW(MaterialOverrides(l), UsageError);
  }
}

TEST(CarLook, LightTogglesLeaveOutLevelsAndPeaks) {
  lighting::SgLighting light;
  light.constant = {0.1f, 0.1f, 0.1f};
  light.levels.push_back({0, 2.0, {0, 3}, {{1, 1, 1}, {2, 2, 2}}});
  light.levels.push_back({1, 8.0, {5}, {{3, 3, 3}}});
  light.peaks.push_back({{0, 1, 0}, 3000, {100, 90, 80}});
  CarLook look;
  const auto all = ApplyLightToggles(light, look);
  EXPECT_EQ(all.sg_count(), light.sg_count());
  look.levels[1] = false;
  auto some = ApplyLightToggles(light, look);
  EXPECT_EQ(some.levels[0].indices.size(), 2u);
  EXPECT_TRUE(some.levels[1].indices.empty());
  EXPECT_EQ(some.peaks.size(), 1u);
  look.peaks = false;
  some = ApplyLightToggles(light, look);
  EXPECT_TRUE(some.peaks.empty());
  EXPECT_EQ(some.sg_count(), 1 + 2);  // the constant and level 0
  // At the peak's axis the sun was nearly all of it.
  EXPECT_LT(some.Evaluate({0, 1, 0}).x, 0.1 * light.Evaluate({0, 1, 0}).x);
}

struct Change {
  int car = 0;      // changed pixels on the car or its shadow
  int other = 0;    // changed pixels elsewhere
  double mean = 0;  // mean |Δ| over the changed ones (linear, summed over channels)
};

// What a look changed relative to `base`; `where` marks the car and its shadow.
Change Compare(const sphere::EquirectImage& base, const sphere::EquirectImage& image, const std::vector<bool>& where) {
  Change c;
  double sum = 0;
  for (int y = 0; y < base.height; ++y)
    for (int x = 0; x < base.width; ++x) {
      const float* p = base.at(x, y);
      const float* q = image.at(x, y);
      const double d = std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]);
      if (d <= 0.01) continue;
      (where[static_cast<std::size_t>(y * base.width + x)] ? c.car : c.other)++;
      sum += d;
    }
  if (c.car + c.other > 0) c.mean = sum / (c.car + c.other);
  return c;
}

TEST(CarLookGL, EveryPanelControlChangesTheRenderedCar) {
  gl::HeadlessContext context;
  AugmentedOptions o;
  o.video = (kDemo / "street.mp4").string();
  o.trajectory = (kDemo / "trajectory_gt.json").string();
  o.car = (kDemo / "car.glb").string();
  o.lighting_levels = 3;
  o.voxel_resolution = 64;
  o.cone_rings = 0;
  AugmentedScene scene(o);
  const int w = 160, h = 90;
  AugmentedView view, bare;
  bare.draw_car = false;
  // dt = 0: the light's smoothing stands still, so only the look differs between renders.
  const auto render = [&](const CarLook& look) {
    scene.SetLook(look);
    return scene.Render(w, h, view, 0).image;
  };
  const CarLook gltf;
  const sphere::EquirectImage base = render(gltf);
  const sphere::EquirectImage background = scene.Render(w, h, bare, 0).image;
  std::vector<bool> car(static_cast<std::size_t>(w) * h);
  int car_count = 0;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) {
      const float* p = base.at(x, y);
      const float* q = background.at(x, y);
      car[static_cast<std::size_t>(y * w + x)] =
          std::abs(p[0] - q[0]) + std::abs(p[1] - q[1]) + std::abs(p[2] - q[2]) > 1e-4;
      car_count += car[static_cast<std::size_t>(y * w + x)];
    }
  ASSERT_GT(car_count, 300);
  const AugmentedFrame figures = scene.Render(w, h, view, 0);
  // The figures the panel shows: the light frame's levels as its transform reported them.
  ASSERT_EQ(figures.light_levels.size(), 3u);
  for (const auto& l : figures.light_levels) {
    EXPECT_GT(l.srbfs_kept, 0);
    EXPECT_LT(l.residue_after, l.residue_before) << "level " << l.level;
  }

  CarLook phong = gltf;
  phong.model = CarLook::Model::kPhong;
  CarLook ct = gltf;
  ct.model = CarLook::Model::kCookTorrance;
  const sphere::EquirectImage phong_image = render(phong), ct_image = render(ct);
  struct Case {
    std::string name;
    const sphere::EquirectImage* against;
    CarLook look;
  };
  std::vector<Case> cases;
  cases.push_back({"Phong instead of glTF", &base, phong});
  cases.push_back({"Cook-Torrance instead of glTF", &base, ct});
  auto with = [](CarLook l, auto edit) {
    edit(l);
    return l;
  };
  cases.push_back({"colour", &phong_image, with(phong, [](CarLook& l) { l.colour = {0.05f, 0.1f, 0.6f}; })});
  cases.push_back({"kd/ks mix", &phong_image, with(phong, [](CarLook& l) { l.ks = 0.8; })});
  cases.push_back({"Phong n", &phong_image, with(phong, [](CarLook& l) { l.phong_n = 3; })});
  cases.push_back({"roughness", &ct_image, with(ct, [](CarLook& l) { l.roughness = 0.9; })});
  cases.push_back({"Fresnel F0", &ct_image, with(ct, [](CarLook& l) { l.fresnel_f0 = 1.0; })});
  for (int level = 0; level < 3; ++level)
    cases.push_back({"level " + std::to_string(level) + " off", &base,
                     with(gltf, [level](CarLook& l) { l.levels[static_cast<std::size_t>(level)] = false; })});
  for (const auto& c : cases) {
    const Change d = Compare(*c.against, render(c.look), car);
    EXPECT_GT(d.car, car_count / 20) << c.name;
    EXPECT_EQ(d.other, 0) << c.name << ": only the car and its shadow may change";
    std::printf("%-30s %5d of %d car/shadow pixels changed, mean |d| %.3f\n", c.name.c_str(), d.car, car_count, d.mean);
  }
  // And back: the first look renders as it did.
  const Change back = Compare(base, render(gltf), car);
  EXPECT_EQ(back.car + back.other, 0);
}

// The demo's street is an 8-bit video whose light has no peak (no sun stands out of it), so the
// peak toggles are shown on the same car and renderer under a sky with a sun: leaving the peak
// out of the light, or its cone out of the shadowing, changes the car and its shadow.
TEST(CarLookGL, PeakAndConeTogglesChangeTheCarUnderASun) {
  gl::HeadlessContext context;
  const scene::GltfScene car = scene::LoadGltfScene(kDemo / "car.glb");
  render::RenderOptions ro;
  ro.lighting_levels = 3;
  ro.voxel_resolution = 64;
  ro.cone_rings = 0;
  render::TripleProductRenderer renderer(car, glm::dmat4(1.0), ro);
  lighting::SgLighting sunny = odvr::testing::FullLighting(3, odvr::testing::SkyRadiance);
  sunny.peaks.push_back({glm::normalize(glm::dvec3(-0.5, 0.6, 0.4)), 3000.0, glm::vec3(2000.f, 1900.f, 1700.f)});
  sphere::EquirectImage sky(64, 32);
  for (float& v : sky.rgb) v = 0.3f;
  renderer.SetEnvironment(sky);
  const auto camera = render::PinholeCamera::LookAt({-6, 2.5, 5}, {0, 0.7, 0}, 40, 160, 90);
  const auto draw = [&](const CarLook& look) {
    renderer.SetLighting(ApplyLightToggles(sunny, look));
    renderer.SetPeakCones(look.cones);
    return renderer.Render(camera);
  };
  const CarLook on;
  const render::RenderResult base = draw(on);
  ASSERT_GT(base.counts.car_pixels, 300);
  ASSERT_EQ(base.counts.peaks, 1);
  std::vector<bool> everywhere(base.composite.rgb.size() / 3, true);
  CarLook no_peaks = on, no_cones = on;
  no_peaks.peaks = false;
  no_cones.cones = false;
  for (const auto& [name, look] : {std::pair{"peaks off", no_peaks}, std::pair{"peak cones off", no_cones}}) {
    const Change d = Compare(base.composite, draw(look).composite, everywhere);
    EXPECT_GT(d.car, base.counts.car_pixels / 20) << name;
    std::printf("%-30s %5d pixels changed (car: %d pixels), mean |d| %.3f\n", name, d.car, base.counts.car_pixels,
                d.mean);
  }
  // The material overrides take effect between frames too.
  CarLook blue = on;
  blue.model = CarLook::Model::kPhong;
  blue.colour = {0.05f, 0.1f, 0.6f};
  renderer.SetMaterials(MaterialOverrides(blue));
  const Change d = Compare(base.composite, draw(on).composite, everywhere);
  EXPECT_GT(d.car, base.counts.car_pixels / 2);
  renderer.SetMaterials({});
  EXPECT_EQ(Compare(base.composite, draw(on).composite, everywhere).car, 0);
}

}  // namespace
}  // namespace odvr::app
