#include "engine/lighting/lighting_errors.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <glm/geometric.hpp>

#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"

namespace odvr::lighting {
namespace {

// ∫ max(0, n·ω) G(ω) dω summed over a fine equirect grid (σ of level 3 is 3° = 34 pixels).
double NumericalDiffuse(const glm::dvec3& n, const glm::dvec3& axis, double lambda) {
  constexpr int kWidth = 4096, kHeight = 2048;
  // Only the rows within 25° of the axis' latitude: beyond, G < 1e-12.
  const double lat = std::asin(axis.y) * 180 / kPi;
  const int row0 = std::max(0, static_cast<int>((90 - lat - 25) / 180 * kHeight));
  const int row1 = std::min(kHeight, static_cast<int>((90 - lat + 25) / 180 * kHeight) + 1);
  double sum = 0;
  for (int row = row0; row < row1; ++row) {
    const double da = sphere::EquirectPixelSolidAngle(row, kWidth, kHeight);
    for (int col = 0; col < kWidth; ++col) {
      const glm::dvec3 w = sphere::EquirectPixelDirection(col, row, kWidth, kHeight);
      const double g = std::exp(lambda * (glm::dot(w, axis) - 1));
      if (g < 1e-12) continue;
      sum += std::max(0.0, glm::dot(n, w)) * g * da;
    }
  }
  return sum;
}

TEST(LightingErrors, SharpLobesAreConvolvedWithTheCosineAtTheirMeanCosine) {
  // A level-3 SG (λ = 364.5) counted as a point of its energy is 1/λ = 0.27 % too bright under
  // the clamped cosine: as large as the diffuse errors the bench compares.
  const auto& hp = sphere::Healpix(3);
  SgLighting model;
  model.levels.push_back({3, hp.Lambda(), {100}, {glm::vec3(1)}});
  const glm::dvec3 axis = hp.centre(100);
  // Directions 0°, 40° and 70° from the lobe's axis.
  const glm::dvec3 side = glm::normalize(glm::cross(axis, glm::dvec3(0.3, 0.5, 0.8)));
  std::vector<glm::dvec3> dirs;
  for (double deg : {0.0, 40.0, 70.0}) {
    const double a = deg * kPi / 180;
    dirs.push_back(std::cos(a) * axis + std::sin(a) * side);
  }
  const Convolutions conv = LightingErrorEvaluator::ConvolveModel(model, dirs);
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    const double expected = NumericalDiffuse(dirs[i], axis, hp.Lambda());
    EXPECT_NEAR(conv.diffuse[i].x / expected, 1.0, 3e-4) << "direction " << i;
  }
}

TEST(LightingErrors, SharpLobesAtTheCosinesHorizonAreNotCutInHalf) {
  // Directions whose horizon passes through a level-3 or level-4 lobe. Counted as a point at its
  // axis, the lobe contributes max(0, n·a): 0 on the horizon, where half of it is above, about
  // 2 % (level 3) of its energy off; on the 18 maps that error, summed over the lobes near any
  // direction's horizon, exceeded the diffuse errors the bench compares (3e-4 on apartment).
  for (int level : {3, 4}) {
    const auto& hp = sphere::Healpix(level);
    SgLighting model;
    model.levels.push_back({level, hp.Lambda(), {7}, {glm::vec3(1)}});
    const glm::dvec3 axis = hp.centre(7);
    const glm::dvec3 side = glm::normalize(glm::cross(axis, glm::dvec3(0.3, 0.5, 0.8)));
    const double sigma_deg = 180 / kPi / std::sqrt(hp.Lambda());
    std::vector<glm::dvec3> dirs;
    for (double k : {-3.0, -1.0, 0.0, 0.5, 1.0, 2.0, 4.0}) {
      const double a = (90 - k * sigma_deg) * kPi / 180;  // the axis k σ above the horizon
      dirs.push_back(std::cos(a) * axis + std::sin(a) * side);
    }
    const Convolutions conv = LightingErrorEvaluator::ConvolveModel(model, dirs);
    const double overhead = NumericalDiffuse(axis, axis, hp.Lambda());
    for (std::size_t i = 0; i < dirs.size(); ++i) {
      const double expected = NumericalDiffuse(dirs[i], axis, hp.Lambda());
      EXPECT_NEAR(conv.diffuse[i].x / overhead, expected / overhead, 5e-4) << "level " << level << " direction " << i;
    }
  }
}

TEST(LightingErrors, ASunIsConvolvedAtItsOwnPixelsNotAtAGridCell) {
  // A 3×3-pixel sun 4e4× a dim sky at 2048×1024, placed off the 256-wide grid's cell centres:
  // the input's convolutions must equal the sum over the full-resolution pixels. Resampled to
  // the grid first, the sun moved by up to 0.35° and diffuse and glossy20 were 0.3–0.6 % off.
  sphere::EquirectImage image(2048, 1024, 0.05f);
  for (int row = 301; row < 304; ++row)
    for (int col = 1203; col < 1206; ++col) std::fill_n(image.at(col, row), 3, 2000.0f);
  const glm::dvec3 sun = sphere::EquirectPixelDirection(1204, 302, 2048, 1024);
  const glm::dvec3 side = glm::normalize(glm::cross(sun, glm::dvec3(0, 1, 0)));
  std::vector<glm::dvec3> dirs;
  for (double deg : {0.0, 5.0, 30.0, 60.0}) {
    const double a = deg * kPi / 180;
    dirs.push_back(std::cos(a) * sun + std::sin(a) * side);
  }
  const Convolutions conv = LightingErrorEvaluator::ConvolveImage(image, dirs);
  for (std::size_t i = 0; i < dirs.size(); ++i) {
    double diffuse = 0, glossy20 = 0;
    for (int row = 0; row < image.height; ++row) {
      const double da = sphere::EquirectPixelSolidAngle(row, image.width, image.height);
      for (int col = 0; col < image.width; ++col) {
        const double c = glm::dot(dirs[i], sphere::EquirectPixelDirection(col, row, image.width, image.height));
        diffuse += image.at(col, row)[0] * std::max(0.0, c) * da;
        glossy20 += image.at(col, row)[0] * std::exp(20 * (c - 1)) * da;
      }
    }
    EXPECT_NEAR(conv.diffuse[i].x / diffuse, 1.0, 2e-3) << "direction " << i;
    EXPECT_NEAR(conv.glossy20[i].x / glossy20, 1.0, 2e-3) << "direction " << i;
  }
}

TEST(LightingErrors, AModelsOwnImageIsJudgedFinerThanTheDeepestLevelsErrors) {
  // The errors are only as fine as the input's numerical convolution: a model's own image must
  // score near zero against the model's closed-form convolutions, below the 1e-4 (glossy) and 2e-5
  // (diffuse) at which the transform's levels 4 and 5 are judged. On 256- and 512-wide grids
  // this scored 1.2-1.9e-4 (glossy-20) on the transform's models, so adding level 5 seemed to raise
  // errors that were the evaluator's own.
  SgLighting model;
  model.constant = glm::vec3(1.0f);
  std::uint32_t state = 12345;
  const auto uniform = [&] {
    state = state * 1664525u + 1013904223u;
    return (state >> 8) / 16777216.0;
  };
  for (int i = 0; i < 300; ++i) {
    const double z = 2 * uniform() - 1, phi = 2 * kPi * uniform(), r = std::sqrt(1 - z * z);
    const double lambda = std::array{22.55, 91.5, 364.51, 1449.29, 5797.0}[static_cast<std::size_t>(i % 5)];
    const float a = static_cast<float>(2 * uniform() - 0.5);
    model.peaks.push_back(
        {glm::dvec3(r * std::cos(phi), z, r * std::sin(phi)), lambda, glm::vec3(a, 0.8f * a, 0.6f * a)});
  }
  const sphere::EquirectImage image = model.Reconstruct(2048, 1024);
  const LightingErrors e = LightingErrorEvaluator(image).Evaluate(model);
  EXPECT_LT(e.diffuse, 1e-5);
  EXPECT_LT(e.glossy20, 4e-5);
  EXPECT_LT(e.glossy200, 5e-5);
  std::printf("own image: diffuse %.2e glossy20 %.2e glossy200 %.2e\n", e.diffuse, e.glossy20, e.glossy200);
}

}  // namespace
}  // namespace odvr::lighting
