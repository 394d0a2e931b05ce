// Area resampling (the lighting levels' working grids, the peak detector's grid, SH's grid) and
// bilinear magnification, against references computed here from their definitions.
#include "engine/sphere/resample.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>

#include "engine/core/error.h"

namespace odvr::sphere {
namespace {

EquirectImage RandomHdr(int w, int h, unsigned seed) {
  EquirectImage image(w, h);
  std::mt19937 rng(seed);
  std::lognormal_distribution<float> value(0.f, 2.f);  // a few pixels thousands of times the rest
  for (float& v : image.rgb) v = value(rng);
  return image;
}

// Output pixel (i, j) is the mean of the input over the rectangle it covers in image coordinates:
// each input pixel weighted by the area of its overlap with that rectangle, in double.
EquirectImage BruteForceArea(const EquirectImage& in, int w, int h) {
  EquirectImage out(w, h);
  const double sx = static_cast<double>(in.width) / w, sy = static_cast<double>(in.height) / h;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      double acc[3] = {0, 0, 0};
      for (int y = 0; y < in.height; ++y) {
        const double oy = std::min(y + 1.0, (j + 1) * sy) - std::max(static_cast<double>(y), j * sy);
        if (oy <= 0) continue;
        for (int x = 0; x < in.width; ++x) {
          const double ox = std::min(x + 1.0, (i + 1) * sx) - std::max(static_cast<double>(x), i * sx);
          if (ox <= 0) continue;
          for (int c = 0; c < 3; ++c) acc[c] += ox * oy * in.at(x, y)[c];
        }
      }
      for (int c = 0; c < 3; ++c) out.at(i, j)[c] = static_cast<float>(acc[c] / (sx * sy));
    }
  return out;
}

void ExpectClose(const EquirectImage& a, const EquirectImage& b, double relative) {
  ASSERT_EQ(a.width, b.width);
  ASSERT_EQ(a.height, b.height);
  for (std::size_t k = 0; k < a.rgb.size(); ++k)
    ASSERT_NEAR(a.rgb[k], b.rgb[k], relative * std::max(1.f, std::abs(b.rgb[k]))) << "value " << k;
}

TEST(Resample, AreaResamplingIsTheCoveredMeanForAnyRatio) {
  const EquirectImage in = RandomHdr(250, 125, 3);
  for (const auto& [w, h] : {std::pair{96, 48}, std::pair{50, 25}, std::pair{249, 124}, std::pair{7, 4}})
    ExpectClose(ResampleArea(in, w, h), BruteForceArea(in, w, h), 2e-5);
}

TEST(Resample, IntegerRatioIsTheBoxAverage) {
  const EquirectImage in = RandomHdr(256, 128, 5);
  const EquirectImage out = ResampleArea(in, 64, 32);
  ExpectClose(out, DownsampleBox(in, 4), 0);
  ExpectClose(out, BruteForceArea(in, 64, 32), 2e-5);
}

TEST(Resample, OneBrightPixelKeepsItsEnergyWhereverItFalls) {
  for (const int x : {0, 17, 100, 199})
    for (const int y : {0, 33, 99}) {
      EquirectImage in(200, 100, 0.f);
      in.at(x, y)[1] = 1e6f;
      const EquirectImage out = ResampleArea(in, 72, 36);  // 25/9 input pixels per output pixel
      double sum = 0;
      for (int j = 0; j < out.height; ++j)
        for (int i = 0; i < out.width; ++i) sum += out.at(i, j)[1];
      // Each output pixel stands for (200/72)·(100/36) input pixels.
      EXPECT_NEAR(sum * (200.0 / 72) * (100.0 / 36), 1e6, 1e6 * 1e-5) << x << "," << y;
    }
}

TEST(Resample, BadSizesAreClearErrors) {
  const EquirectImage in(64, 32, 1.f);
  EXPECT_THROW(ResampleArea(in, 0, 16), Error);
  EXPECT_THROW(ResampleArea(in, 128, 64), Error);
}

TEST(Resample, BilinearMagnificationWrapsAroundTheSeam) {
  EquirectImage in(8, 4, 0.f);
  for (int y = 0; y < 4; ++y) in.at(7, y)[0] = 1.f;  // the last column only
  const EquirectImage out = UpsampleBilinear(in, 16, 8);
  // Output column 0 lies a quarter input pixel left of input column 0's centre: a quarter of
  // the way to column 7 across the seam.
  for (int y = 0; y < 8; ++y) {
    EXPECT_NEAR(out.at(0, y)[0], 0.25f, 1e-6);
    EXPECT_NEAR(out.at(15, y)[0], 0.75f, 1e-6);
    EXPECT_NEAR(out.at(8, y)[0], 0.f, 1e-6);
  }
}

}  // namespace
}  // namespace odvr::sphere
