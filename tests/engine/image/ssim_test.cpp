// image::MeanSsim against values worked out by hand: identical images, a constant image against
// another constant (only the luminance term is left), and a structure-destroying shuffle.
#include "engine/image/ssim.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include "core/error.h"

namespace odvr::image {
namespace {

std::vector<float> Ramp(int w, int h) {
  std::vector<float> v(static_cast<std::size_t>(w) * h);
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w; ++x) v[static_cast<std::size_t>(y) * w + x] = 0.5f + 0.4f * std::sin(0.3f * x + 0.2f * y);
  return v;
}

TEST(Ssim, IdenticalImagesScoreOne) {
  const auto a = Ramp(40, 30);
  EXPECT_NEAR(MeanSsim(a, a, 40, 30, {}), 1.0, 1e-12);
}

TEST(Ssim, ConstantImagesKeepOnlyTheLuminanceTerm) {
  // No variance: SSIM = (2 μa μb + C1) / (μa² + μb² + C1), C1 = 0.01².
  const std::vector<float> a(20 * 20, 0.5f), b(20 * 20, 0.25f);
  const double c1 = 1e-4;
  EXPECT_NEAR(MeanSsim(a, b, 20, 20, {}), (2 * 0.5 * 0.25 + c1) / (0.25 + 0.0625 + c1), 1e-6);
}

TEST(Ssim, ShuffledStructureScoresLowAndTheMaskSelects) {
  const int w = 40, h = 30;
  const auto a = Ramp(w, h);
  auto b = a;
  std::mt19937 rng(3);
  std::shuffle(b.begin(), b.end(), rng);  // same histogram, no structure
  const double s = MeanSsim(a, b, w, h, {});
  EXPECT_LT(s, 0.3);
  // Only the left half differs: a mask over the right half (away from the window's reach) scores 1.
  auto c = a;
  for (int y = 0; y < h; ++y)
    for (int x = 0; x < w / 2; ++x) c[static_cast<std::size_t>(y) * w + x] = b[static_cast<std::size_t>(y) * w + x];
  std::vector<float> right(a.size(), 0.f);
  for (int y = 0; y < h; ++y)
    for (int x = w / 2 + 6; x < w; ++x) right[static_cast<std::size_t>(y) * w + x] = 1.f;
  EXPECT_NEAR(MeanSsim(a, c, w, h, right), 1.0, 1e-9);
  EXPECT_LT(MeanSsim(a, c, w, h, {}), 0.8);
  EXPECT_THROW(MeanSsim(a, c, w, h, std::vector<float>(a.size(), 0.f)), Error);
  EXPECT_THROW(MeanSsim(a, c, w, h + 1, {}), Error);
  EXPECT_THROW(MeanSsim(a, c, w, h, {}, 0.0), Error);
}

}  // namespace
}  // namespace odvr::image
