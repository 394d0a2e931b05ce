#include "engine/sphere/equirect.h"

#include <gtest/gtest.h>

#include <glm/geometric.hpp>

namespace odvr::sphere {
namespace {

TEST(Equirect, CentreColumnLooksForwardAndColumnsGrowToTheRight) {
  const int w = 1024, h = 512;
  const auto forward = EquirectDirection(w / 2.0, h / 2.0, w, h);
  EXPECT_NEAR(forward.x, 1, 1e-12);
  const auto right = EquirectDirection(w * 0.75, h / 2.0, w, h);
  EXPECT_NEAR(right.z, 1, 1e-12);  // +Z is right
  const auto left = EquirectDirection(w * 0.25, h / 2.0, w, h);
  EXPECT_NEAR(left.z, -1, 1e-12);
}

TEST(Equirect, SeamIsTheImageEdgeLookingBackward) {
  const int w = 1024, h = 512;
  EXPECT_NEAR(EquirectDirection(0, h / 2.0, w, h).x, -1, 1e-12);
  EXPECT_NEAR(EquirectDirection(w, h / 2.0, w, h).x, -1, 1e-12);
}

TEST(Equirect, RowZeroIsTheZenith) {
  EXPECT_NEAR(EquirectDirection(10, 0, 64, 32).y, 1, 1e-12);
  EXPECT_NEAR(EquirectDirection(10, 32, 64, 32).y, -1, 1e-12);
}

TEST(Equirect, PixelRoundTripEverywhereButThePoles) {
  const int w = 300, h = 150;
  for (int row = 0; row < h; ++row) {
    for (int col = 0; col < w; col += 7) {
      const auto d = EquirectPixelDirection(col, row, w, h);
      EXPECT_NEAR(glm::length(d), 1, 1e-12);
      const auto p = EquirectPixel(d, w, h);
      EXPECT_NEAR(p.x, col + 0.5, 1e-9);
      EXPECT_NEAR(p.y, row + 0.5, 1e-9);
    }
  }
}

TEST(Equirect, SolidAnglesSumToTheSphere) {
  for (auto [w, h] : {std::pair{8, 4}, {1024, 512}, {2048, 1024}, {7, 3}}) {
    double sum = 0;
    for (int row = 0; row < h; ++row) sum += w * EquirectPixelSolidAngle(row, w, h);
    EXPECT_NEAR(sum, 4 * kPi, 1e-9) << w << "x" << h;
  }
}

}  // namespace
}  // namespace odvr::sphere
