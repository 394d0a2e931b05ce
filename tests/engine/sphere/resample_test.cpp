// Area resampling (the lighting levels' working grids, the peak detector's grid, SH's grid) and
// bilinear and Lagrange magnification, against references computed here from their definitions.
#include "engine/sphere/resample.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <glm/geometric.hpp>
#include <random>

#include "core/error.h"
#include "engine/sphere/equirect.h"

namespace odvr::sphere {
namespace {

EquirectImage RandomHdr(int w, int h, unsigned seed) {
  EquirectImage image(w, h);
  std::mt19937 rng(seed);
  std::lognormal_distribution<float> value(0.f, 2.f);  // a few pixels thousands of times the rest
  for (float& v : image.rgb) v = value(rng);
  return image;
}

// Output pixel (i, j) is the mean of the input over the part of the sphere it covers: each input
// pixel weighted by the solid angle of its overlap with the output pixel, in double.
EquirectImage BruteForceArea(const EquirectImage& in, int w, int h) {
  EquirectImage out(w, h);
  const double sx = static_cast<double>(in.width) / w, sy = static_cast<double>(in.height) / h;
  for (int j = 0; j < h; ++j)
    for (int i = 0; i < w; ++i) {
      double acc[3] = {0, 0, 0}, weight = 0;
      for (int y = 0; y < in.height; ++y) {
        const double oy = std::min(y + 1.0, (j + 1) * sy) - std::max(static_cast<double>(y), j * sy);
        if (oy <= 0) continue;
        const double y0 = std::max(static_cast<double>(y), j * sy), y1 = std::min(y + 1.0, (j + 1) * sy);
        const double row = (std::cos(kPi * y0 / in.height) - std::cos(kPi * y1 / in.height)) / oy;
        for (int x = 0; x < in.width; ++x) {
          const double ox = std::min(x + 1.0, (i + 1) * sx) - std::max(static_cast<double>(x), i * sx);
          if (ox <= 0) continue;
          for (int c = 0; c < 3; ++c) acc[c] += ox * oy * row * in.at(x, y)[c];
          weight += ox * oy * row;
        }
      }
      for (int c = 0; c < 3; ++c) out.at(i, j)[c] = static_cast<float>(acc[c] / weight);
    }
  return out;
}

// The plain mean of each f×f block, its rows alike.
EquirectImage PlainBlockMean(const EquirectImage& in, int f) {
  EquirectImage out(in.width / f, in.height / f);
  for (int j = 0; j < out.height; ++j)
    for (int i = 0; i < out.width; ++i)
      for (int c = 0; c < 3; ++c) {
        double sum = 0;
        for (int y = j * f; y < (j + 1) * f; ++y)
          for (int x = i * f; x < (i + 1) * f; ++x) sum += in.at(x, y)[c];
        out.at(i, j)[c] = static_cast<float>(sum / (f * f));
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
  // Into kept storage (other size, NaNs): the same; at the input's own size, the input.
  EquirectImage kept(7, 300, std::nanf(""));
  kept.Reshape(64, 32);
  ResampleArea(in, &kept);
  ExpectClose(kept, out, 0);
  kept.Reshape(256, 128);
  ResampleArea(in, &kept);
  EXPECT_EQ(kept.rgb, in.rgb);
}

double SphereIntegral(const EquirectImage& image, int channel) {
  double sum = 0;
  for (int row = 0; row < image.height; ++row) {
    double row_sum = 0;
    for (int col = 0; col < image.width; ++col) row_sum += image.at(col, row)[channel];
    sum += row_sum * EquirectPixelSolidAngle(row, image.width, image.height);
  }
  return sum;
}

TEST(Resample, OneBrightPixelKeepsItsEnergyWhereverItFalls) {
  for (const int x : {0, 17, 100, 199})
    for (const int y : {0, 1, 33, 99}) {
      EquirectImage in(200, 100, 0.f);
      in.at(x, y)[1] = 1e6f;
      const double energy = SphereIntegral(in, 1);
      // 25/9 input pixels per output pixel, and 4×4 blocks: Σ value·dA is what it was, in the
      // polar rows too.
      EXPECT_NEAR(SphereIntegral(ResampleArea(in, 72, 36), 1), energy, energy * 1e-5) << x << "," << y;
      EXPECT_NEAR(SphereIntegral(ResampleArea(in, 50, 25), 1), energy, energy * 1e-5) << x << "," << y;
    }
}

TEST(Resample, AreaResamplingKeepsTheIntegralOfASignedImage) {
  // A residue: noise of both signs, and rows of alternating sign near the north pole (a lamp's
  // overshoot and undershoot), whose integral is small beside its values.
  EquirectImage in(512, 256);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise;
  for (float& v : in.rgb) v = noise(rng);
  for (int row = 0; row < 24; ++row)
    for (int col = 0; col < in.width; ++col) in.at(col, row)[1] += row % 2 ? 5.f : -5.f;
  const double integral = SphereIntegral(in, 1);
  for (const int width : {256, 128, 64}) {
    const EquirectImage restricted = ResampleArea(in, width, width / 2);
    const EquirectImage plain = PlainBlockMean(in, in.width / width);
    EXPECT_NEAR(SphereIntegral(restricted, 1), integral, 1e-4 * std::abs(integral)) << width;
    // The plain box weighs a footprint's rows alike: near a pole that moves the integral.
    EXPECT_GT(std::abs(SphereIntegral(plain, 1) - integral), 0.5 * std::abs(integral)) << width;
    // Into an image whose storage is reused: the same values.
    EquirectImage reused(width, width / 2, 123.f);
    ResampleArea(in, &reused, nullptr);
    EXPECT_EQ(reused.rgb, restricted.rgb);
  }
  // A constant stays that constant, with whole and with fractional footprints.
  for (const int width : {128, 300}) {
    const EquirectImage constant = ResampleArea(EquirectImage(512, 256, 0.25f), width, width / 2);
    for (const float v : constant.rgb) EXPECT_NEAR(v, 0.25f, 1e-6f) << width;
  }
  EXPECT_THROW(ResampleArea(in, 1024, 512), Error);
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

// A spherical Gaussian of λ around `axis` sampled at each pixel centre of a w × h grid, with a
// different amplitude per channel.
EquirectImage SampledSg(const glm::dvec3& axis, double lambda, int w, int h) {
  EquirectImage image(w, h);
  for (int row = 0; row < h; ++row)
    for (int col = 0; col < w; ++col) {
      const double g = std::exp(lambda * (glm::dot(EquirectPixelDirection(col, row, w, h), axis) - 1));
      for (int c = 0; c < 3; ++c) image.at(col, row)[c] = static_cast<float>(g * (1 + c));
    }
  return image;
}

double MaxAbsDifference(const EquirectImage& a, const EquirectImage& b) {
  double worst = 0;
  for (std::size_t k = 0; k < a.rgb.size(); ++k) worst = std::max(worst, std::abs(double(a.rgb[k]) - b.rgb[k]));
  return worst;
}

TEST(Resample, LagrangeMagnificationFollowsAGaussianAcrossTheSeamAndOverThePoles) {
  // The lighting transform magnifies its coarser levels' reconstruction by 2 at each level; the
  // finest Gaussians in it have σ = 4.3 coarse pixels (level s−2 on level s−1's grid). Here
  // λ = 5.5 (level 0's) on a 64 × 32 grid: σ = 24.4°, 4.3 pixels of 5.6°, magnified to 128 × 64
  // and compared with the Gaussian sampled there, wherever its peak lies.
  const double lambda = 5.5;
  for (const glm::dvec3 axis : {glm::dvec3(1, 0, 0), glm::dvec3(-1, 0, 0.01), glm::dvec3(0.1, 1, 0),
                                glm::dvec3(0, -1, 0.2), glm::normalize(glm::dvec3(-1, 0.5, 0))}) {
    const glm::dvec3 a = glm::normalize(axis);
    SCOPED_TRACE(testing::Message() << "axis " << a.x << " " << a.y << " " << a.z);
    const EquirectImage coarse = SampledSg(a, lambda, 64, 32), fine = SampledSg(a, lambda, 128, 64);
    // Peak amplitude 3 (the blue channel): 2e-5 of it, where the bilinear one is off by 8e-3.
    const double lagrange = MaxAbsDifference(MagnifyLagrange(coarse, 128, 64), fine);
    const double bilinear = MaxAbsDifference(UpsampleBilinear(coarse, 128, 64), fine);
    EXPECT_LT(lagrange, 3 * 3e-5);
    EXPECT_GT(bilinear, 3 * 3e-3);
    // By 4 as well: σ = 4.3 coarse pixels still.
    EXPECT_LT(MaxAbsDifference(MagnifyLagrange(coarse, 256, 128), SampledSg(a, lambda, 256, 128)), 3 * 3e-5);
  }
}

TEST(Resample, LagrangeMagnificationKeepsAConstantAndFallsBackToBilinear) {
  const EquirectImage constant(16, 8, 2.5f);
  for (const float v : MagnifyLagrange(constant, 48, 24).rgb) ASSERT_NEAR(v, 2.5f, 2e-6);
  EXPECT_EQ(MagnifyLagrange(constant, 16, 8).rgb, constant.rgb);
  // Sizes the six-sample stencil does not fit: the bilinear magnification, bit for bit.
  const EquirectImage odd = SampledSg(glm::dvec3(1, 0, 0), 5.5, 15, 8),
                      small = SampledSg(glm::dvec3(1, 0, 0), 5.5, 4, 2);
  EXPECT_EQ(MagnifyLagrange(odd, 30, 16).rgb, UpsampleBilinear(odd, 30, 16).rgb);
  EXPECT_EQ(MagnifyLagrange(small, 8, 4).rgb, UpsampleBilinear(small, 8, 4).rgb);
  EXPECT_EQ(MagnifyLagrange(constant, 24, 12).rgb, UpsampleBilinear(constant, 24, 12).rgb);  // 1.5x
  EXPECT_THROW(MagnifyLagrange(constant, 8, 4), Error);
}

TEST(Resample, LagrangeMagnificationIntoKeptStorageWritesEveryPixel) {
  // The lighting transform magnifies into images it keeps across frames: whatever the target
  // held (another size, NaNs), the result is the returning overload's, bit for bit.
  const EquirectImage coarse = SampledSg(glm::normalize(glm::dvec3(0.3, 0.9, -0.2)), 5.5, 64, 32);
  for (const auto& [w, h] : {std::pair{128, 64}, std::pair{256, 128}, std::pair{96, 48}}) {
    EquirectImage target(300, 7, std::nanf(""));
    MagnifyLagrange(coarse, w, h, &target);
    EXPECT_EQ(target.width, w);
    EXPECT_EQ(target.height, h);
    EXPECT_EQ(target.rgb, MagnifyLagrange(coarse, w, h).rgb) << w;
  }
  EquirectImage same = coarse;
  EXPECT_THROW(MagnifyLagrange(same, 128, 64, &same), Error);
}

}  // namespace
}  // namespace odvr::sphere
