#include "engine/lighting/reference_fits.h"

#include <gtest/gtest.h>

#include <cmath>
#include <glm/geometric.hpp>

#include "engine/lighting/lighting_errors.h"
#include "engine/lighting/residual_transform.h"
#include "engine/sphere/equirect.h"
#include "engine/sphere/healpix.h"
#include "tests/engine/lighting/lighting_test_maps.h"

namespace odvr::lighting {
namespace {

TEST(ReferenceFits, LeastSquaresRecoversAMapMadeOfItsOwnBasis) {
  // A map that is exactly 0.2 + two level-1 SGs: the optimum on levels 0–1 must find them.
  SgLighting truth;
  truth.constant = glm::vec3(0.2f);
  SgLevel l1;
  l1.level = 1;
  l1.lambda = sphere::Healpix(1).Lambda();
  l1.indices = {5, 30};
  l1.amplitudes = {glm::vec3(1.0f, 0.5f, 0.25f), glm::vec3(2.0f)};
  truth.levels.push_back(l1);
  const auto image = truth.Reconstruct(256, 128);
  LeastSquaresReport report;
  const SgLighting fit = LeastSquaresSgFit(image, 2, &report);
  EXPECT_EQ(report.unknowns, 1 + 12 + 48);
  EXPECT_LT(RelativeL2(image, fit.Reconstruct(256, 128)), 2e-3);
  EXPECT_NEAR(fit.levels[1].amplitudes[5].x, 1.0f, 0.02f);
  EXPECT_NEAR(fit.levels[1].amplitudes[30].y, 2.0f, 0.04f);
}

TEST(ReferenceFits, LeastSquaresIsNoWorseThanTheTransformInL2) {
  auto frame = testing::SkyMap(256, 128);
  testing::AddDisc(&frame, {0.3, 0.6, -0.4}, 0.06, 40.f);
  for (int levels : {2, 3}) {
    ResidualTransformOptions o;
    o.levels = levels;
    o.stop_threshold = 0;
    o.keep_threshold = 0;
    const double transform = RelativeL2(frame, ResidualTransform(o).Run(frame).Reconstruct(256, 128));
    const double optimum = RelativeL2(frame, LeastSquaresSgFit(frame, levels).Reconstruct(256, 128));
    EXPECT_LE(optimum, transform * 1.001) << levels;
  }
}

TEST(ReferenceFits, SphericalHarmonicsReproduceALowOrderFunctionAndConverge) {
  // 1 + y + 0.5 x z lies in bands 0–2: order 2 reproduces it; order 1 cannot.
  sphere::EquirectImage image(128, 64);
  for (int row = 0; row < 64; ++row)
    for (int col = 0; col < 128; ++col) {
      const auto d = sphere::EquirectPixelDirection(col, row, 128, 64);
      float* p = image.at(col, row);
      p[0] = p[1] = p[2] = static_cast<float>(1 + d.y + 0.5 * d.x * d.z);
    }
  EXPECT_LT(RelativeL2(image, ProjectSphericalHarmonics(image, 2).Reconstruct(128, 64)), 1e-3);
  EXPECT_GT(RelativeL2(image, ProjectSphericalHarmonics(image, 1).Reconstruct(128, 64)), 0.05);
  const glm::dvec3 d = glm::normalize(glm::dvec3(0.3, -0.5, 0.8));
  EXPECT_NEAR(ProjectSphericalHarmonics(image, 2).Evaluate(d).x, 1 + d.y + 0.5 * d.x * d.z, 2e-3);

  auto sky = testing::SkyMap(256, 128);
  double previous = 1e9;
  for (int order : {2, 4, 8, 16}) {
    const double e = RelativeL2(sky, ProjectSphericalHarmonics(sky, order).Reconstruct(256, 128));
    EXPECT_LT(e, previous) << order;
    previous = e;
  }
}

}  // namespace
}  // namespace odvr::lighting
