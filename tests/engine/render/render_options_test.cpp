// RenderOptions (engine/render/triple_product_renderer.h): Check refuses every value out of its
// range and the modes that do not combine; the shading lanes a render picks by its first pass's size.
#include "engine/render/triple_product_renderer.h"

#include <gtest/gtest.h>

#include <limits>

#include "core/error.h"
#include "engine/render/triple_product_internal.h"

namespace odvr::render {
namespace {

TEST(RenderOptions, CheckRefusesEachValueOutOfRangeAndModesThatDoNotCombine) {
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

// shade_lanes 0 (the default): 4 lanes only where one invocation per pixel would leave a GPU
// mostly idle (320×180, as the H200 measured: 7.4 ms against 12.4), 1 where the pass fills it
// (1280×720: 27.0 against 35.7 with 4) and on a CPU rasterizer at any size.
TEST(RenderOptions, FourShadeLanesOnlyOnSmallPassesOnAGpu) {
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

}  // namespace
}  // namespace odvr::render
