// Both players take their engine options from one CarRendering (app/ar/car_rendering.h): what the
// command line sets must reach the renderer and the lighting builder, and a bad value must be
// refused naming its option before anything is loaded.
#include "app/ar/car_rendering.h"

#include <gtest/gtest.h>

#include <string>

#include "app/ar/augmented_scene.h"
#include "app/ar/live_scene.h"
#include "core/error.h"

namespace odvr::app {
namespace {

std::string CheckMessage(const CarRendering& c) {
  try {
    c.Check();
  } catch (const UsageError& e) {
    return e.what();
  }
  return "";
}

TEST(CarRendering, RenderAndLightingOptionsCarryEverySetting) {
  CarRendering c;
  c.lighting_levels = 3;
  c.lighting_width = 128;
  c.voxel_resolution = 128;
  c.cone_rings = 2;
  c.shading_rate = 2;
  const render::RenderOptions r = c.Render();
  EXPECT_EQ(r.lighting_levels, 3);
  EXPECT_EQ(r.voxel_resolution, 128);
  EXPECT_EQ(r.cone_rings, 2);
  EXPECT_EQ(r.supersample, 1);
  EXPECT_EQ(r.shading_rate, 2);
  EXPECT_FALSE(r.read_layers) << "a player shows the composite alone";
  EXPECT_TRUE(r.read_composite);
  const lighting::LightingOptions l = c.Lighting();
  EXPECT_EQ(l.transform.levels, 3);
  EXPECT_EQ(l.peak_grid_width, 128);

  c.supersample = 2;
  c.composite_on_gpu = true;
  EXPECT_EQ(c.Render().supersample, 2);
  EXPECT_EQ(c.Render().shading_rate, 1) << "supersampling shades every sample it keeps";
  EXPECT_FALSE(c.Render().read_composite) << "a window's composite stays on the GPU";
  EXPECT_NO_THROW(c.Render().Check());
}

TEST(CarRendering, BadSettingsNameTheirOption) {
  EXPECT_EQ(CheckMessage(CarRendering{}), "");
  const auto with = [](auto change) {
    CarRendering c;
    change(c);
    return CheckMessage(c);
  };
  EXPECT_NE(with([](CarRendering& c) { c.lighting_levels = 7; }).find("--levels"), std::string::npos);
  EXPECT_NE(with([](CarRendering& c) { c.lighting_width = 15; }).find("lighting width"), std::string::npos);
  EXPECT_NE(with([](CarRendering& c) { c.voxel_resolution = 100; }).find("--voxels"), std::string::npos);
  EXPECT_NE(with([](CarRendering& c) { c.cone_rings = 4; }).find("cone rings"), std::string::npos);
  EXPECT_NE(with([](CarRendering& c) { c.supersample = 0; }).find("--supersample"), std::string::npos);
  EXPECT_NE(with([](CarRendering& c) { c.shading_rate = 3; }).find("--shading-rate"), std::string::npos);
}

TEST(CarRendering, BothPlayersCheckIt) {
  AugmentedOptions a;
  a.video = "v.mp4";
  a.trajectory = "t.json";
  a.car = "car.glb";
  EXPECT_NO_THROW(a.Check());
  a.voxel_resolution = 100;
  EXPECT_THROW(a.Check(), UsageError);
  LiveSceneOptions l;
  l.rig = "rig.json";
  EXPECT_NO_THROW(l.Check());
  l.shading_rate = 3;
  EXPECT_THROW(l.Check(), UsageError);
}

}  // namespace
}  // namespace odvr::app
